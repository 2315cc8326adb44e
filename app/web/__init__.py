"""The self-contained 3D page: its models (:mod:`.models`), their packed data (:mod:`.pack`),
the page itself (:mod:`.page`) and the bundled viewer (``viewer/``, built from ``web/``)."""
