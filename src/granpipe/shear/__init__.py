"""granpipe.shear: the sheared annular cell (docs/shear.md), the drum paper's Ref. [20]
under the drum's law. Modules by role: model (the cell), preparation (placement, growth,
steady shear), protocol (one replica), measures (the rearrangement detector), fits,
stages, layout, cli. Figures: :mod:`granpipe.figures.shear`."""
