"""The sheared annular cell (docs/shear.md)."""
