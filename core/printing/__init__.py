"""3D printing: checks that parts print (:mod:`.checks`, with :mod:`.profiles`, :mod:`.solid`,
:mod:`.thickness`, :mod:`.gaps`, :mod:`.seams`, :mod:`.locate`) and optional fixes
(:mod:`.fixes`). Units are mm, mm², mm³."""
