"""Recording a run: the built-in synthetic bench (simulator + renderer behind the daq
fakes) and the capture loop that writes the MCAP log."""
