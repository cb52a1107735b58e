"""Vision: dimensional measurement from SLRA range images (patches, edges, fits).

Entry points: `measure.measure(frame, spec, ctx)` -> VisionResult | VisionException,
`measure.scan_for(spec, ctx)`, `regions.planar_regions(frame)`, `render.render_measurement`.
Vision sees only the frame, the nominal part and its placement: never the simulator nor the
as-built truth.
"""
