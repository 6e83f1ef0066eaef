"""QuadPiPS' superpixel planar regions (Asselmeier et al., Sections V-A, V-D, V-E): a second
terrain segmenter beside S3, with the same input and output (an elevation map in, convex
foothold polygons on planes out) and the opposite bet (segment by geometry, no memory).

Typical use (the S3 process runs it when its ``method`` param is ``superpixels``)::

    params = runtime.params.load(SuperpixelParams, "hw_config/gains/superpixels.yaml")
    seg = SuperpixelSegmenter(params)
    result = seg.segment(elevation, resolution, origin_xy)
    result.footholds      # runtime.geometry.Foothold, world frame
    result.safe_mask      # the cells SLIC clustered (health check, steppable)
    result.labels         # the superpixels (-1: none)

Grid convention: cell (i, j) has its centre at origin + (j, i) * resolution (lcmtypes).
"""

from processes.superpixels.params import SuperpixelParams
from processes.superpixels.segmenter import STAGES, SuperpixelResult, SuperpixelSegmenter

__all__ = ["STAGES", "SuperpixelParams", "SuperpixelResult", "SuperpixelSegmenter"]
