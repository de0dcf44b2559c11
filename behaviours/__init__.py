"""The core behaviours: thin py_trees leaves over chaser_bt calls.

Importing this package registers every leaf with the tree registry: it is named in the
``chaser_bt.behaviours`` entry-point group, which the registry loads on first use, and it imports
each of its modules here, so a new behaviour module needs no other wiring.
"""

import importlib
import pkgutil

for _module in pkgutil.iter_modules(__path__):
    importlib.import_module(f"{__name__}.{_module.name}")
