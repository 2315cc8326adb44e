"""Quadric-error decimation of a whole SurfaceSet (seams decimated once for both labels, shells kept
closed with their topology, the error measured in mm) and progressive levels of detail."""
