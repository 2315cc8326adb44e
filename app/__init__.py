"""The application: the recipe every door fills (:mod:`.recipe`), the stage functions
(:mod:`.stages`), the one flow that chains them (:mod:`.run`), its files (:mod:`.outputs`) and
report (:mod:`.report`), the check flow for mesh files (:mod:`.check`) and the command line
(:mod:`.cli`). Imports core, never the add-on."""
