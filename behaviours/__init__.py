"""The core behaviours: thin py_trees leaves over chaser_bt calls (see chaser_bt.tree.registry)."""
