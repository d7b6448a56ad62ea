"""granpipe.column: the tapped column study (docs/column.md; Blackmore et al. 2011).

* :mod:`~granpipe.column.model` — the column's parameters (Eqs. 2–3, 16–19) and the
  equilibrium start of Eq. (27).
* :mod:`~granpipe.column.discrete` — the discrete column of Eq. (19) and its tangent
  dynamics with saltation (jitted).
* :mod:`~granpipe.column.continuum` — the long-wave, BSR and derived BSR continuum
  models (jitted).
* :mod:`~granpipe.column.protocol` — the runs: Fig. 1 trajectories, relaxation batches,
  Lyapunov points, the continuum comparison and convergence.
* :mod:`~granpipe.column.measures` — relaxation ensemble, return-map periods, chaos map.
* :mod:`~granpipe.column.fits` — the relaxation fit, summary rows, the Theorem 1 note.
* :mod:`~granpipe.column.stages` — the file-to-file stages behind ``granpipe column
  <stage>`` (:mod:`~granpipe.column.cli`); :mod:`~granpipe.column.layout` — the config
  subset of each rule and the file names (used by ``workflow/rules/column.smk`` and
  ``granpipe status``).

The column has no separate preparation: the start is the closed-form equilibrium,
perturbed per replica inside the runs.
"""
