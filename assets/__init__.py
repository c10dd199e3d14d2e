"""Shipped robots (robot.toml + tet meshes); regenerate with make_robots.py."""
