"""Road networks, the static world mesh and geometry: the ground floor."""
