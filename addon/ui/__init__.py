"""The sidebar tab: property groups (settings), panels and lists, isovalue presets."""
