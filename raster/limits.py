"""The image sizes this package renders, checked before anything is allocated or written.

- A side of at most MAX_SIDE (8192) pixels. The visibility pass reads its RG32UI target back with
  glReadPixels, 8 bytes a pixel: at 16384 x 16384 that is 2 GiB in one buffer, and the read
  segfaulted (exit 139) instead of failing; Mesa's llvmpipe accepts renderbuffers of that size, so
  the GL limits alone (GL_MAX_RENDERBUFFER_SIZE, GL_MAX_VIEWPORT_DIMS, also checked once a context
  exists: raster.visibility) do not protect the process.
- Memory: a process rendering a frame holds about BYTES_PER_PIXEL bytes per pixel (the ids read
  back, every float buffer, Dr.Jit's temporaries; measured ~218 B/px with every buffer asked for,
  from peak RSS at 1024^2 and 2048^2, rounded up) on top of BASE_BYTES; an 8192^2 render went over
  12 GB. `check_memory` compares that with the memory available now.
"""
from __future__ import annotations

from scenes.description import MAX_SIDE

BYTES_PER_PIXEL = 256
# A kept raster frame's buffers, bytes per pixel each (raster.frames.BUFFERS; tested against a render)
BUFFER_BYTES = {"color": 12, "albedo": 12, "normal": 12, "motion": 8, "depth": 4, "prev_depth": 4,
                "object_id": 4, "prim_id": 4, "light_mask": 4}
BASE_BYTES = 600 * 2 ** 20     # the interpreter, Dr.Jit, Mitsuba, the EGL context, scene data


class SizeError(ValueError):
    """An image size this machine or this package cannot render; the message names where it came from."""


def check_size(width: int, height: int, where: str) -> tuple[int, int]:
    """(width, height) if both sides are whole numbers in 8..MAX_SIDE, else SizeError naming `where`."""
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, int) or not 8 <= v <= MAX_SIDE:
            raise SizeError(f"{where}: {name} {v!r} is outside 8..{MAX_SIDE} pixels (the largest side "
                            "the raster renders)")
    return width, height


def memory_need(width: int, height: int, processes: int = 1) -> int:
    """Bytes `processes` processes rendering width x height frames at once need (the module notes)."""
    return processes * (BASE_BYTES + BYTES_PER_PIXEL * int(width) * int(height))


def frame_bytes(width: int, height: int, buffers) -> int:
    """Bytes of one kept raster frame of these buffers (colour always)."""
    return int(width) * int(height) * sum(BUFFER_BYTES[b] for b in set(buffers) | {"color"})


def available_memory() -> int:
    """Bytes of memory available to new allocations now (psutil; the kernel's MemAvailable)."""
    import psutil
    return int(psutil.virtual_memory().available)


def check_memory(width: int, height: int, where: str, processes: int = 1) -> int:
    """The memory need of rendering width x height in `processes` processes; SizeError naming
    `where`, the size, the need and what is available when the need is more."""
    need, have = memory_need(width, height, processes), available_memory()
    if need > have:
        per = f" in each of {processes} worker processes" if processes > 1 else ""
        raise SizeError(f"{where}: {width}x{height} needs about {need / 2 ** 30:.1f} GiB of memory{per} "
                        f"({BYTES_PER_PIXEL} B/pixel), {have / 2 ** 30:.1f} GiB is available")
    return need
