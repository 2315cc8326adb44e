"""Smoothing with a bound on how far a vertex moves: the filters, their constraints (voxel cell,
max deviation), the guards (fold guard, volume restoration, untangle) and the driver that runs
them for every door (:mod:`.driver`)."""
