"""Vision: dimensional measurement from SLRA range images (patches, edges, fits).

Entry points: `measure.measure(frame, spec, ctx)` -> VisionResult | VisionException,
`measure.scan_for(spec, ctx)`, `measure.frames_for(spec, ctx)` and
`measure.measure_frames(frames, spec, ctx)` (several approaches averaged),
`regions.planar_regions(frame)`, `render.render_measurement`.
Vision sees only the frame, the nominal part and its placement: never the simulator nor the
as-built truth.
"""
