"""The results file (schema, reading and writing, comparison metrics) and the dataset of
a simulation on its own."""
