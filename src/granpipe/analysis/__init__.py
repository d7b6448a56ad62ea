"""granpipe.analysis: what every study uses — ensemble reduction, smoothing, bootstrap,
regression, event-aligned averages, summary rows. Study-specific measures and fits live
in the study's package.

Plain numpy / xarray in, labelled results out; nothing here knows the engine.
Import from the submodules (this package imports nothing, so that loading one
submodule does not pull in the others, or pandas):

- :mod:`.ensemble` — streaming (replica, time) batch reduction, batch means.
- :mod:`.smoothing` — moving average λ̄ (drum Eq. 2), FFT low-pass.
- :mod:`.bootstrap` — windowed polynomial fits (vertex, zero crossing) with fit errors,
  percentile bootstrap over replicas or batches.
- :mod:`.summary` — ``summary.csv`` rows and atomic writes.
- :mod:`.regression` — segmented log–log regression, Arrhenius fits.
- :mod:`.events` — event-aligned averages: replicas shifted onto their own event times.
"""
