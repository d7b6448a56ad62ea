"""granpipe.analysis."""
