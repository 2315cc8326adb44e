"""The flow every door runs: the recipe (:mod:`.recipe`, settings defined once), the stage
functions (:mod:`.stages`), the one chain of them (:mod:`.run`), the files of a run
(:mod:`.outputs`) and its report (:mod:`.report`); preprocessing, print-part tools and cut to fit
as the flow applies them; the check flow for mesh files (:mod:`.check_files`)."""
