"""granpipe.drum."""
