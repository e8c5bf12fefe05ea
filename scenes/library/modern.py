"""Hard cases of today's engines: glossy metal (the glTF metallic-roughness model, shading/brdf.py)
and alpha-tested foliage, in motion. Each isolates a case that modern TAAs treat specially: the
luminance weighting of Karis (2014), anti-flicker and luma-instability passes.

specular_shimmer  a normal-mapped, polished metal plate under a point light, slow camera pan
specular_rail     polished metal rails and wires, one to a few pixels thick, slow camera pan
foliage_sway      alpha-tested leaf cards swaying about their stems (object spin), static camera
modern_mix        a brushed metal plate, two rails and swaying cards, slow camera pan
texture_crawl     a fine trilinear checker floor at a grazing angle, the camera creeping forward

Highlights are kept moderate (roughness >= 0.3, dim lights): the agreement check's interior
error is absolute, and a bright, sharp lobe amplifies the last-bit differences between the
raster's and the reference's hit points (docs/method.md, shading model); the display's key and
white point follow the frame's own luminance, so a dim scene shows as a bright one. Normal maps are
filtered bilinearly: with nearest texels, a pixel centre within rounding of a texel boundary picks
different texels in the two renderers (measured: 1-5 such pixels a frame at 320x180, errors up to 0.5).

What their references cost under the figures' precision rule (docs/method.md) was set here too:
a point light shades every pixel of a flat wall differently across the pixel, so every pixel got
the reference's replicates; a sun leaves flat surfaces constant (8 samples), and the samples go to
the edges, rails and bumps. A shimmer that No AA barely shows (bumps 2-4 px across: No AA was the
best column at 43.6 dB) gives figures of tiny MSE, whose reference uncertainty asks for fine bounds;
sub-pixel bumps make the aliasing, and so the figures, large against the reference's noise.
"""
from __future__ import annotations

import numpy as np

from ..description import (Camera, DirectionalLight, Material, Motion, PointLight, Scene, SceneObject, Texture,
                           Transform)
from . import geometry as g
from .common import QUICK, SKY, WALL, _leaf_alpha

STEEL = (0.62, 0.62, 0.64)        # base colours of metals (glTF: F0 of a metal)
BRASS = (0.85, 0.68, 0.38)
FRAMES = 48                       # two ghosting tests' worth (24 frames each)
CRAWL_SQUARES = 64                # texture_crawl's checker: 64x64 texels, each one square


# -- procedural normal maps -----------------------------------------------------------------------
def _smooth_noise(shape: tuple[int, int], sigma: tuple[float, float], seed: int) -> np.ndarray:
    """Periodic white noise low-passed by a Gaussian of `sigma` texels (rows, columns), unit std."""
    rng = np.random.default_rng(seed)
    n = rng.standard_normal(shape)
    fy = np.fft.fftfreq(shape[0])[:, None]
    fx = np.fft.fftfreq(shape[1])[None, :]
    gain = np.exp(-2 * np.pi ** 2 * ((fy * sigma[0]) ** 2 + (fx * sigma[1]) ** 2))
    h = np.real(np.fft.ifft2(np.fft.fft2(n) * gain))
    return h / h.std()


def normal_map_from_height(h: np.ndarray, slope: float) -> np.ndarray:
    """A tangent-space normal map (H, W, 3), texels (n + 1) / 2, of the height field `h` (texel
    units, periodic) scaled so that its gradient's std is `slope`; row 0 is v = 0."""
    dv = (np.roll(h, -1, 0) - np.roll(h, 1, 0)) / 2
    du = (np.roll(h, -1, 1) - np.roll(h, 1, 1)) / 2
    k = slope / max(float(np.hypot(du, dv).std()), 1e-12)
    n = np.stack([-k * du, -k * dv, np.ones_like(h)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return ((n + 1) / 2).astype(np.float32)


def bumps_normal_map(size: int = 128, seed: int = 21, sigma: float = 1.2, slope: float = 0.15) -> np.ndarray:
    """Fine hammered bumps, a few texels (`sigma`) across, their gradient's std `slope` (0.15: the
    normal tilted ~9 degrees)."""
    return normal_map_from_height(_smooth_noise((size, size), (sigma, sigma), seed), slope)


def brushed_normal_map(size: int = 128, seed: int = 23) -> np.ndarray:
    """Brushed grooves along v: a height that varies across the columns (u), barely along them;
    across the view (u) the UVs are least sensitive to the hit point's rounding at a grazing angle."""
    return normal_map_from_height(_smooth_noise((size, size), (12.0, 1.0), seed), 0.2)


def _floor(x0, x1, z_near, z_far, y=0.0) -> g.MeshData:
    """A horizontal rectangle facing up, UVs over [0,1]^2 (u along x, v from near to far)."""
    return g.moved(g.rect(x0, x1, -z_near, -z_far), (0.0, y, 0.0), (1, 0, 0), -90.0)


# -- specular shimmer -----------------------------------------------------------------------------
def specular_shimmer() -> Scene:
    plate = Material(albedo=BRASS, metallic=1.0, roughness=0.35,
                     normal_map=Texture(kind="array", data=bumps_normal_map(256, sigma=1.0, slope=0.2),
                                        filter="bilinear"))
    return Scene(
        name="specular_shimmer", resolution=QUICK, frames=FRAMES, transport="direct",
        description="A hammered brass plate (metallic 1, roughness 0.35, a bilinear 256x256 normal map of "
                    "bumps about a pixel across) lit from behind by the sun, whose glossy reflection "
                    "fills the plate's middle, the camera panning 0.006 units a frame",
        stresses="specular aliasing: a glossy highlight broken by sub-pixel normal detail sparkles under "
                 "jitter and camera motion, with no geometric edge for edge detection or clamping to see",
        camera=Camera(position=(-0.15, 1.6, 2.2), target=(-0.15, 0.0, -0.4), yfov_deg=45, near=0.1, far=30,
                      velocity=(0.006, 0.0, 0.0), target_velocity=(0.006, 0.0, 0.0)),
        objects=(SceneObject(name="plate", mesh=g.spec(_floor(-1.8, 1.8, 1.2, -2.4)), material=plate),
                 SceneObject(name="wall", mesh=g.spec(g.rect(-4.0, 4.0, -0.5, 3.0, -2.5)),
                             material=Material(albedo=WALL))),
        # a sun, not a point light: the wall and the plate's unbumped shading are constant over a
        # pixel, so only the bumps cost reference samples
        lights=(DirectionalLight(direction=(0.1, -0.55, 0.83), intensity=(0.02, 0.0194, 0.018)),),
        ambient=(0.05, 0.05, 0.054), background=SKY)


# -- specular highlights on thin geometry ---------------------------------------------------------
RAIL_DIAMETERS_PX = (0.5, 1.0, 1.5, 2.5, 4.0)      # at the quick resolution, at the rails' distance
_RAIL_CAM = dict(position=(0.0, 0.2, 3.0), target=(0.0, 0.0, 0.0), yfov_deg=40.0)


def _rail(name: str, radius: float, at, tilt_deg: float, material: Material,
          length: float = 6.0) -> SceneObject:
    """A smooth open tube along x (tilted `tilt_deg` in the x-y plane) centred at `at`, 24 sides,
    cut into 64 lengths: a 6-unit triangle a few thousandths wide would make the barycentrics
    across it, so the interpolated normal, depend on float rounding (~1e-3 relative at a highlight)."""
    path = np.stack([np.linspace(-length / 2, length / 2, 65), np.zeros(65), np.zeros(65)], -1)
    return SceneObject(name=name, mesh=g.spec(g.tubes(path[None], radius, sides=24)), material=material,
                       transform=Transform(translate=tuple(float(c) for c in at), rotate_axis=(0, 0, 1),
                                           rotate_deg=tilt_deg))


def specular_rail() -> Scene:
    px = 2 * 3.0 * np.tan(np.radians(_RAIL_CAM["yfov_deg"]) / 2) / QUICK.quick[1]
    steel = Material(albedo=STEEL, metallic=1.0, roughness=0.3)
    rails = [_rail(f"rail_{i}", d * px / 2, (0.0, 0.8 - 0.4 * i, 0.0), (-4.0, 2.0, -1.0, 3.0, 0.5)[i], steel)
             for i, d in enumerate(RAIL_DIAMETERS_PX)]
    return Scene(
        name="specular_rail", resolution=QUICK, frames=FRAMES, transport="direct",
        description="Five polished steel rails (metallic 1, roughness 0.3, 64 x 24-sided tubes) of 0.5, 1, 1.5, 2.5 and 4 px "
                    "diameter, nearly horizontal, before a dark wall, lit by two point lights; the camera "
                    "rises 0.004 units a frame",
        stresses="specular highlights on thin geometry: a highlight line thinner than a pixel on a rail "
                 "about a pixel wide appears and vanishes under jitter and slow motion",
        camera=Camera(**_RAIL_CAM, near=0.1, far=30, velocity=(0.0, 0.004, 0.0)),
        objects=(*rails,
                 SceneObject(name="wall", mesh=g.spec(g.rect(-5.0, 5.0, -3.0, 3.0, -1.0)),
                             material=Material(albedo=(0.1, 0.1, 0.12)))),
        # suns, not point lights: the wall is constant over a pixel, so only the rails cost samples
        lights=(DirectionalLight(direction=(0.3, -0.5, -0.8), intensity=(0.03, 0.029, 0.028)),
                DirectionalLight(direction=(-0.4, 0.3, -0.85), intensity=(0.018, 0.019, 0.021))),
        ambient=(0.06, 0.06, 0.066), background=SKY)


# -- alpha-tested foliage swaying -----------------------------------------------------------------
def _card(w: float, h: float) -> g.MeshData:
    """A leaf card w x h in the x-y plane, its origin at the stem (bottom middle): it sways about it."""
    return g.rect(-w / 2, w / 2, 0.0, h)


def leaf_cards(n: int, rng: np.random.Generator, centre=(0.0, 0.0, 0.0), spread=(1.3, 0.7),
               sway_deg: float = 0.25, size=(0.32, 0.8)) -> list[SceneObject]:
    """`n` cut-out leaf cards standing around `centre` (+- `spread` in x and z), each spinning
    `sway_deg` (+-30 %) a frame about a horizontal axis through its stem, half one way, half the other."""
    leaf = Texture(kind="array", data=_leaf_alpha())
    out = []
    for i in range(n):
        yaw = float(rng.uniform(-60, 60))
        axis = (float(np.cos(np.radians(yaw))), 0.0, float(-np.sin(np.radians(yaw))))
        sway = sway_deg * float(rng.uniform(0.7, 1.3)) * (1 if i % 2 else -1)
        out.append(SceneObject(
            name=f"leaf_{i}", mesh=g.spec(_card(*size)),
            material=Material(albedo=(0.1, float(0.3 + 0.35 * rng.random()), 0.07), alpha=leaf),
            transform=Transform(translate=(centre[0] + float(rng.uniform(-spread[0], spread[0])), centre[1],
                                           centre[2] + float(rng.uniform(-spread[1], spread[1]))),
                                rotate_axis=(0, 1, 0), rotate_deg=yaw),
            motion=Motion(spin_axis=axis, spin_deg=sway)))
    return out


def foliage_sway() -> Scene:
    objs = [SceneObject(name="ground", mesh=g.spec(_floor(-3.0, 3.0, 2.0, -3.0)),
                        material=Material(albedo=(0.3, 0.25, 0.18)))]
    objs += leaf_cards(12, np.random.default_rng(17))
    return Scene(
        name="foliage_sway", resolution=QUICK, frames=FRAMES, transport="direct",
        description="Twelve alpha-tested leaf cards over soil, each swaying 0.25 degrees a frame (+-30 %) "
                    "about its stem (object spin), lit by the sun (no shadows: alpha-tested shadow rays made "
                    "its references several times dearer); static camera",
        stresses="alpha-tested foliage in motion: cut-out edges that geometry-based edge detection "
                 "cannot see, moving under a still camera",
        camera=Camera(position=(0.0, 0.9, 2.8), target=(0.0, 0.4, 0.0), yfov_deg=45, near=0.1, far=30),
        objects=tuple(objs), lights=(DirectionalLight(direction=(-0.4, -1.0, -0.5), intensity=(2.0, 1.95, 1.8)),),
        ambient=(0.2, 0.22, 0.25), background=SKY)


# -- combined -------------------------------------------------------------------------------------
def modern_mix() -> Scene:
    plate = Material(albedo=STEEL, metallic=1.0, roughness=0.3,
                     normal_map=Texture(kind="array", data=brushed_normal_map(), filter="bilinear"))
    rail = Material(albedo=BRASS, metallic=1.0, roughness=0.25)
    objs = [SceneObject(name="plate", mesh=g.spec(_floor(-1.6, 1.6, 1.0, -1.4)), material=plate),
            SceneObject(name="wall", mesh=g.spec(g.rect(-4.0, 4.0, -0.5, 3.0, -2.2)), material=Material(albedo=WALL)),
            _rail("rail_0", 0.012, (0.0, 0.75, -0.9), 0.0, rail),
            _rail("rail_1", 0.006, (0.0, 0.45, -0.9), 1.5, rail)]
    objs += leaf_cards(5, np.random.default_rng(29), centre=(0.0, 0.0, -1.2), spread=(1.2, 0.3), size=(0.3, 0.7))
    return Scene(
        name="modern_mix", resolution=QUICK, frames=FRAMES, transport="direct",
        description="A brushed steel plate (bilinear 128x128 normal map of grooves, roughness 0.3), two brass rails "
                    "(1.5 and 0.75 px) and five swaying cut-out leaf cards, a point light; the camera pans "
                    "0.005 units a frame",
        stresses="today's hard cases together: specular shimmer on a normal-mapped metal, a highlight on "
                 "thin rails and moving alpha-tested cards, under one history",
        # off the texel grid on purpose (as in disocclusion): a camera on it puts pixel centres on
        # texel boundaries, where the two renderers' nearest-texel lookups may differ by float rounding
        camera=Camera(position=(-0.2137, 1.0, 2.4), target=(-0.2137, 0.3, -0.8), yfov_deg=45, near=0.1, far=30,
                      velocity=(0.00513, 0.0, 0.0), target_velocity=(0.00513, 0.0, 0.0)),
        objects=tuple(objs), lights=(PointLight(position=(0.5, 1.6, -0.2), intensity=(0.55, 0.53, 0.5)),),
        ambient=(0.14, 0.14, 0.15), background=SKY)


# -- texture crawl --------------------------------------------------------------------------------
def _grid_floor(x0, x1, z_near, z_far, cells=(8, 16), repeat=(1.0, 1.0), y=0.0) -> g.MeshData:
    """A horizontal rectangle facing up cut into `cells` (x, z) quads, UVs over [0, repeat] (u along
    x, v from near to far; the texture wraps): small triangles keep the UV a pixel centre gets
    within float rounding in both renderers, where a fine texture turns a UV error into a value error."""
    xs, zs = np.linspace(x0, x1, cells[0] + 1), np.linspace(-z_near, -z_far, cells[1] + 1)
    X, Z = np.meshgrid(xs, zs)
    v = np.stack([X, np.full_like(X, y), Z], -1).reshape(-1, 3)
    uv = np.stack([(X - x0) / (x1 - x0) * repeat[0], (-Z - z_near) / (z_far - z_near) * repeat[1]], -1).reshape(-1, 2)
    n = cells[0] + 1
    i, j = np.meshgrid(np.arange(cells[0]), np.arange(cells[1]))
    a = (j * n + i).ravel()
    faces = np.concatenate([np.stack([a, a + n, a + n + 1], -1), np.stack([a, a + n + 1, a + 1], -1)])
    return g.MeshData(v, faces, uv, np.tile([0.0, 1.0, 0.0], (len(v), 1)))


def texture_crawl() -> Scene:
    checker = Texture(kind="checker", squares=CRAWL_SQUARES, color_a=(0.62, 0.6, 0.55), color_b=(0.12, 0.12, 0.13),
                      filter="trilinear")
    return Scene(
        name="texture_crawl", resolution=QUICK, frames=FRAMES, transport="direct",
        description="A floor of 1-texel checker squares (64x64 texels, trilinear, tiled to 5 cm squares) seen "
                    "from 0.45 units above it, a plain wall closing the view; the camera creeps forward 0.01 units a frame",
        stresses="texture crawl: a fine, high-contrast texture minified at a grazing angle; a negative LOD bias "
                 "(temporal upscalers' log2(scale) - 1) samples mip levels finer than the pixel footprint, "
                 "and the aliased pattern crawls as the camera moves",
        camera=Camera(position=(0.0, 0.45, 1.0), target=(0.3, 0.0, -4.0), yfov_deg=45, near=0.1, far=30,
                      velocity=(0.0, 0.0, -0.01), target_velocity=(0.0, 0.0, -0.01)),
        objects=(SceneObject(name="floor", mesh=g.spec(_grid_floor(-3.2, 3.2, 1.0, -5.4, (8, 16), (2.0, 2.0))),
                             material=Material(albedo=(1.0, 1.0, 1.0), texture=checker)),
                 SceneObject(name="wall", mesh=g.spec(g.rect(-4.0, 4.0, -0.5, 3.0, -5.4)),
                             material=Material(albedo=WALL))),
        lights=(DirectionalLight(direction=(-0.3, -1.0, -0.4), intensity=(1.6, 1.6, 1.5)),),
        ambient=(0.2, 0.2, 0.22), background=SKY)
