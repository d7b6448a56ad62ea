"""granpipe.drum: the rotating-drum study (docs/drum.md; Maghsoodi & Luijten 2016).

In protocol order:

* :mod:`~granpipe.drum.model` — the drum of Table 1 (150 wall disks on a 150-gon),
  disk sizes and masses, reduced units, the drum's Ω, the tiny drum for tests.
* :mod:`~granpipe.drum.preparation` — random non-overlapping placement; the start-up
  (fall in the turning drum, or settling in a still one).
* :mod:`~granpipe.drum.protocol` — one replica: placement, start-up, rotate 1°, onset
  window, continuous avalanche, decay window with the drum stopped at 5 s; batches;
  protocol times in steps.
* :mod:`~granpipe.drum.measures` — what a replica records; the run file of a batch.
* :mod:`~granpipe.drum.fits` — ensemble reduction, λ̄ and low-pass, onset vertex, sign
  changes and lags with fit errors and bootstrap intervals.
* :mod:`~granpipe.drum.stages` — the workflow stages init, runs, ensemble, fits, figures.
* :mod:`~granpipe.drum.layout` — the ``drum`` config section (defaults, checks, parameter
  points, the seeding subset), file names under ``results/<scale>/drum/``, and the config
  subset of each rule.
* :mod:`~granpipe.drum.cli` — ``granpipe drum <stage>`` and ``granpipe drum replica``.

One replica by hand::

    from granpipe.drum.protocol import run_replica
    ds = run_replica({}, replica=0)          # the paper's drum, schema defaults
"""
