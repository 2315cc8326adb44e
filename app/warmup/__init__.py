"""The kernel warm-up: compile the numba kernels once (:mod:`.compile`), each step running a stage
on tiny inputs (:mod:`.steps`)."""
