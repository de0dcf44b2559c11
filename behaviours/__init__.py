"""The core behaviours: thin py_trees leaves over chaser_bt calls.

Importing this package registers every leaf with the tree registry (it is named in the
``chaser_bt.behaviours`` entry-point group, which the registry loads on first use).
"""

from behaviours import conditions, goto, hover, landing, takeoff  # noqa: F401  (registration)
