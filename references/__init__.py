"""Ground truth: Mitsuba 3 integrates each pixel's area with the shading the raster uses,
to a convergence target, and caches the result as float32 OpenEXR keyed by content."""
from .cache import ReferenceCache, default_cache_dir
from .render import render_reference
from .result import Reference, ReferenceError
from .tracer import trace_pixel_centres

__all__ = ["Reference", "ReferenceError", "ReferenceCache", "default_cache_dir", "render_reference",
           "trace_pixel_centres"]
