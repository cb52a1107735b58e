"""Vision: dimensional measurement from SLRA range images (patches, edges, fits).

Entry points: `measure.measure(frame, spec, ctx)` -> VisionResult | VisionException,
`measure.measure_frames(frames, spec, ctx)` (several approaches averaged),
`scan.scan_for(spec, ctx)`, `scan.frames_for(spec, ctx)`, `context.VisionContext`,
`regions.planar_regions(frame)`, `render.render_measurement`.
Vision sees only the frame, the nominal part and its placement: never the simulator nor the
as-built truth.
"""
