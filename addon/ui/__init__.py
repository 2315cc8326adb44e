"""The sidebar tab: the settings as property groups (``props``) and the panels that draw them."""
