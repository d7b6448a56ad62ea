"""granpipe.figures."""
