"""Demonstrations of td2adaptor on simulated robots: `td2adaptor demo warehouse` (warehouse.py)."""
