"""Ground truth: labels from the sensors' own rays, and the writers of a dataset."""
