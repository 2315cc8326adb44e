"""The application, in rooms: :mod:`.flow` (the recipe every door fills, the stage functions, the
one chain of them, a run's files and report), :mod:`.cli` (the command line), :mod:`.batch`
(cohorts), :mod:`.web` (the 3D page), :mod:`.pictures` and :mod:`.warmup` (compiling the kernels
once). Imports core, never the add-on."""
