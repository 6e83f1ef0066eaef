"""S3: Stable Steppability Segmentation and convex decomposition (Section VI).

Typical use in the S3 process (one pipeline object per process: it keeps S_{k-1})::

    params = runtime.params.load(S3Params, "hw_config/gains/s3.yaml", "simulation")
    pipe = S3Pipeline(params)
    result = pipe.process(elevation, resolution, origin_xy, map_time_s=t_map, now_s=t_now,
                          lowest=lowest_layer)          # lowest: optional, for LNV
    result.status                     # 'ok', 'no safe terrain', 'stale map', 'all NaN', ...
    for f in result.footholds:        # runtime.geometry.Foothold, world frame:
        f.vertices                    # {p : f.A p <= f.b, f.normal . p = f.offset}, (k, 3)
                                      # CCW corners on the plane
    result.times_ms                   # inpainting, criteria, cleanup, decomposition, plane_fit

Grid convention: cell (i, j) has its centre at origin + (j, i) * resolution (lcmtypes).
"""

from processes.s3.params import S3Params
from processes.s3.pipeline import STAGES, S3Pipeline, S3Result

__all__ = ["STAGES", "S3Params", "S3Pipeline", "S3Result"]
