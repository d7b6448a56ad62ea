"""granpipe.box."""
