"""3D-print readiness on all parts together: the checks (solid, wall thickness, gaps between parts)
and the fixes (tiny shells, holes, clearance, fuse, thicken)."""
