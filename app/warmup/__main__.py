"""``python -m anatomesh.app.warmup``: compile every numba kernel now (:func:`.compile.main`)."""
import sys

from .compile import main

sys.exit(main(program=True))
