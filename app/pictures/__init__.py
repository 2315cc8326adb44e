"""Pictures without a plotting library: isovalue galleries, histograms, captions."""
