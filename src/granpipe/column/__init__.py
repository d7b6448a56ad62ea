"""granpipe.column."""
