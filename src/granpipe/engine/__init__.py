"""granpipe.engine."""
