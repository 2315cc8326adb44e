"""Before extraction: resampling, volume smoothing, label-map interpolation, the fuzzy boundary and
topology clean-up — each a function from a Volume to a Volume, in millimetres."""
