"""granpipe.box: the vibrated-box study (docs/box.md; Fortini & Huang 2015).

Modules, in the order of the protocol:

* :mod:`~granpipe.box.model` — Appendix A in numbers: the engine's box law with Table I,
  Δt = t_c/50 (Eq. A5) rounded to whole sampling phases, the plate drive
  ``z_b = z0 + A r(t) sin(ωt + φ)`` with Γ = A (ω = 1, g = 1) and K_m = Γ².
* :mod:`~granpipe.box.preparation` — crystal sites (orientation A, rows ``spanning`` 20/19
  or ``inset`` 19/19) and random sequential placement; crystal relaxation, random fall
  and settling (Sec. III).
* :mod:`~granpipe.box.protocol` — one run part: smooth start, transient, measured periods
  sampled at N_k phases (tracers, plate, gap, T_g), positions at every cycle start;
  exact continuation across parts.
* :mod:`~granpipe.box.measures` — tracers, s_c, s_b (our correction, docs/box.md),
  detachment, T_g, slips, ψ6/ψ4 and the crystal check; per point: their pooling, ψ6 at
  measurement start, launch speeds.
* :mod:`~granpipe.box.fits` — thresholds in Γ, segmented T_g* regions, Arrhenius E_b,
  summary rows.
* :mod:`~granpipe.box.stages` — the file-to-file stages behind ``granpipe box <stage>``
  (:mod:`~granpipe.box.cli`); :mod:`~granpipe.box.layout` — file names, parameter points
  and the config subset of each stage (used by ``workflow/rules/box.smk`` and
  ``granpipe status``).

Figures: :mod:`granpipe.figures.box`.
"""
