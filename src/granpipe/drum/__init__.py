"""granpipe.drum: the rotating-drum study (docs/drum.md; Maghsoodi & Luijten 2016).

In protocol order:

* :mod:`~granpipe.drum.geometry` — the drum of Table 1 (150 wall disks on a 150-gon),
  disk sizes and masses, reduced units, the tiny drum for tests.
* :mod:`~granpipe.drum.placement` — random non-overlapping placement.
* :mod:`~granpipe.drum.settings` — the ``drum`` config section: defaults, the seeding
  subset, protocol times in steps.
* :mod:`~granpipe.drum.protocol` — one replica: settle, rotate 1°, onset window,
  continuous avalanche, decay window with the drum stopped at 5 s; batches.
* :mod:`~granpipe.drum.records` — what a replica records; the run file of a batch.
* :mod:`~granpipe.drum.fitting` — ensemble reduction, λ̄ and low-pass, fitted times with
  fit errors and bootstrap intervals.
* :mod:`~granpipe.drum.stages` — the workflow stages init, runs, ensemble, fits, figures.
* :mod:`~granpipe.drum.layout` — file names under ``results/<scale>/drum/``.
* :mod:`~granpipe.drum.cli` — ``granpipe drum <stage>`` and ``granpipe drum replica``.

One replica by hand::

    from granpipe.drum.protocol import run_replica
    ds = run_replica({}, replica=0)          # the paper's drum, schema defaults
"""
