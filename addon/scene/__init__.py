"""Blender's scene side: collections, objects and materials (:mod:`.objects`) and a scan's objects
back into one core SurfaceSet (:mod:`.reassemble`)."""
