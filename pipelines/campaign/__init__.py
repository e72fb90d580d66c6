"""Campaigns: many runs processed as Dask tasks, catalogued, swept and reported."""
