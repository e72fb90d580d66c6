"""``beambench bench``: speed against error for each target, with the competitor in the
same run (the paper's image chain, Exudyn's ANCF beam)."""
