"""chaser-bt: behaviour-tree missions for autonomous sUAS, after the CHASER paper."""
__version__ = "0.1.0"
