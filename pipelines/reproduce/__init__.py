"""``beambench reproduce``: the paper's comparisons recomputed, one module per group of
sections, the plots and the report."""
