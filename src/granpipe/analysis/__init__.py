"""granpipe.analysis: ensemble reduction, smoothing, fits, bootstrap, regression.

Plain numpy / xarray in, labelled results out; nothing here knows the engine.
Import from the submodules (this package imports nothing, so that loading one
submodule does not pull in freud or pandas):

- :mod:`.ensemble` — streaming (replica, time) batch reduction, batch means.
- :mod:`.smoothing` — moving average λ̄ (drum Eq. 2), FFT low-pass.
- :mod:`.fits` — onset / sign-change / lag fits with fit errors and bootstrap CIs.
- :mod:`.summary` — ``summary.csv`` rows and atomic writes.
- :mod:`.box` — tracers, s_c, s_b, detachment, T_g, slips, ψ6/ψ4 (box App. B, Eq. 2).
- :mod:`.regression` — segmented log–log regression, Arrhenius fits.
- :mod:`.thresholds` — thresholds in Γ on a grid.
"""
