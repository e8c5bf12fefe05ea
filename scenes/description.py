"""Declarative scene description: validated the same way from Python, TOML or JSON.

Units: world units for lengths, degrees for angles, linear Rec.709 RGB for colours. Animation is
per frame (frame index t = 0, 1, ...): an object's pose at t is its base transform followed by
`velocity * t` and a rotation of `spin_deg * t` about `spin_axis` through its own origin.

Every number must be finite (TOML's `nan`/`inf` and JSON's `NaN`/`Infinity` are rejected) and every
direction non-zero: such a value would otherwise reach the renderers as an empty or NaN image.
"""
from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_serializer, model_validator

Vec3 = tuple[float, float, float]
RGB = tuple[Annotated[float, Field(ge=0)], Annotated[float, Field(ge=0)], Annotated[float, Field(ge=0)]]

TRANSPORTS = ("unlit", "direct", "direct_shadows", "path")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, arbitrary_types_allowed=True,
                              allow_inf_nan=False)


def _nonzero(v: Vec3) -> Vec3:
    if not np.any(np.asarray(v, float)):
        raise ValueError("must be a non-zero direction")
    return v


def _check_view(position: Vec3, target: Vec3) -> None:
    f = np.subtract(target, position, dtype=float)
    if not np.all(np.isfinite(f)):
        raise ValueError(f"target - position overflows: position {position}, target {target}")
    if np.allclose(f, 0):
        raise ValueError(f"position {position} and target {target} coincide (no view direction)")


class CameraCut(_Strict):
    frame: int = Field(ge=0)
    position: Vec3
    target: Vec3

    @model_validator(mode="after")
    def _check(self):
        _check_view(self.position, self.target)
        return self


class Camera(_Strict):
    # position/target may be left out only when a glTF object supplies its camera (camera = true);
    # then every field set here overrides the glTF camera's.
    position: Optional[Vec3] = None
    target: Optional[Vec3] = None
    up: Vec3 = (0.0, 1.0, 0.0)
    yfov_deg: float = Field(45.0, gt=0, lt=180)
    near: float = Field(0.1, gt=0)
    far: float = Field(100.0, gt=0)
    velocity: Vec3 = (0.0, 0.0, 0.0)          # position change per frame
    target_velocity: Vec3 = (0.0, 0.0, 0.0)
    cuts: tuple[CameraCut, ...] = ()          # hard cuts: the pose jumps, history must reset

    @model_validator(mode="after")
    def _check(self):
        if self.far <= self.near:
            raise ValueError(f"far ({self.far}) must be greater than near ({self.near})")
        if self.position is not None and self.target is not None:
            _check_view(self.position, self.target)
        return self

    _up = field_validator("up")(_nonzero)


class Texture(_Strict):
    """An image addressed by UV in [0,1)^2 with wrap-around; row 0 is v in [0, 1/H)."""
    kind: Literal["image", "checker", "array"]
    path: Optional[str] = None            # image: PNG/JPEG, sRGB-encoded, converted to linear
    squares: int = Field(8, ge=1)         # checker
    color_a: RGB = (1.0, 1.0, 1.0)
    color_b: RGB = (0.0, 0.0, 0.0)
    data: Optional[np.ndarray] = Field(None, exclude=True)  # array: (H, W, 3) or (H, W) float32, linear
    # the raster's lookup (docs/method.md, "Texture filtering"): nearest texel; bilinear on the base
    # level; or trilinear over a mip chain at the pixel's UV footprint plus the column's LOD bias.
    # The reference integrates the base level (bilinear unless nearest) over each pixel's area.
    filter: Literal["nearest", "bilinear", "trilinear"] = "nearest"
    # trilinear: added to the study column's LOD bias (a sampler's own bias, as engines set per texture)
    lod_bias: float = Field(0.0, ge=-4.0, le=4.0)

    @model_serializer(mode="wrap")
    def _dump(self, handler):
        # left out at their defaults, so a nearest-texel scene's content hash stays the one it had
        out = handler(self)
        if self.filter == "nearest":
            out.pop("filter", None)
        if self.lod_bias == 0.0:
            out.pop("lod_bias", None)
        return out

    @model_validator(mode="after")
    def _check(self):
        if self.kind == "image" and not self.path:
            raise ValueError("kind 'image' needs a 'path'")
        if self.kind == "array":
            if self.data is None or self.data.ndim not in (2, 3):
                raise ValueError("kind 'array' needs 'data' of shape (H, W) or (H, W, 3)")
            if self.data.size == 0:
                raise ValueError(f"texture data is empty (shape {self.data.shape})")
            if not np.all(np.isfinite(self.data)):
                raise ValueError("texture data contains NaN or Inf")
        if self.lod_bias and self.filter != "trilinear":
            raise ValueError(f"lod_bias applies to filter 'trilinear' only (filter {self.filter!r})")
        return self


_Unit = Annotated[float, Field(ge=0, le=1)]


class Material(_Strict):
    """Lambert (albedo) unless it declares `roughness`, `metallic` > 0, a `metallic_roughness` or a
    `normal_map` texture: then the glTF 2.0 metallic-roughness model (shading/brdf.py), with
    `albedo` as the base colour and metallic 0 / roughness 1 where left out. Texture roles follow
    glTF: texture and emission_texture are colour (sRGB files), the others data (linear files)."""
    albedo: RGB = (0.8, 0.8, 0.8)
    emission: RGB = (0.0, 0.0, 0.0)       # radiance added to the shaded colour (lamps, HDR tests)
    texture: Optional[Texture] = None     # multiplies albedo
    alpha: Optional[Texture] = None       # cut-out: a sample is kept where alpha >= alpha_threshold
    alpha_threshold: float = Field(0.5, gt=0, le=1)
    metallic: Optional[_Unit] = None
    roughness: Optional[_Unit] = None     # perceptual roughness; the GGX alpha is its square
    metallic_roughness: Optional[Texture] = None   # G multiplies roughness, B metallic (glTF)
    normal_map: Optional[Texture] = None  # tangent space, (2 * texel - 1) * (scale, scale, 1)
    normal_scale: float = 1.0
    emission_texture: Optional[Texture] = None     # multiplies emission
    occlusion: Optional[Texture] = None   # R scales the ambient term only
    occlusion_strength: _Unit = 1.0

    @model_serializer(mode="wrap")
    def _dump(self, handler):
        # Fields left at their defaults stay out of dumps, so a Lambert scene's content hash (and
        # every cache key made from it) is the one it had before these fields existed.
        out = handler(self)
        for k in _MATERIAL_EXTRAS:
            if getattr(self, k) == Material.model_fields[k].default:
                out.pop(k, None)
        return out

    @property
    def is_gltf_model(self) -> bool:
        """True where the material needs the metallic-roughness model (else it is exactly Lambert)."""
        return (self.roughness is not None or bool(self.metallic) or self.metallic_roughness is not None
                or self.normal_map is not None)


_MATERIAL_EXTRAS = ("metallic", "roughness", "metallic_roughness", "normal_map", "normal_scale",
                    "emission_texture", "occlusion", "occlusion_strength")


class MeshSpec(_Strict):
    kind: Literal["box", "plane", "sphere", "cylinder", "file", "arrays", "gltf"]
    size: Vec3 = (1.0, 1.0, 1.0)          # box extents; plane uses x, y; cylinder radius=x, height=y
    radius: float = Field(0.5, gt=0)      # sphere
    segments: int = Field(32, ge=3)       # sphere / cylinder tessellation
    uv_scale: tuple[float, float] = (1.0, 1.0)
    smooth: bool = False                  # interpolated vertex normals (sphere, cylinder, files)
    path: Optional[str] = None            # file: OBJ / PLY / glTF as one mesh; gltf: the whole file
    # gltf: its first camera is the scene's (scenes/gltf.py). Left out of dumps: a gltf mesh is
    # expanded before anything is hashed, and other kinds' hashes stay as they were.
    camera: bool = Field(False, exclude=True)
    # arrays: built in code; vertices (V,3), faces (F,3), optional uvs (V,2), normals (V,3)
    vertices: Optional[np.ndarray] = Field(None, exclude=True)
    faces: Optional[np.ndarray] = Field(None, exclude=True)
    uvs: Optional[np.ndarray] = Field(None, exclude=True)
    normals: Optional[np.ndarray] = Field(None, exclude=True)

    @model_validator(mode="after")
    def _check(self):
        if self.kind in ("file", "gltf") and not self.path:
            raise ValueError(f"kind {self.kind!r} needs a 'path'")
        if self.camera and self.kind != "gltf":
            raise ValueError("'camera' applies to kind 'gltf' only")
        if self.kind == "arrays" and (self.vertices is None or self.faces is None):
            raise ValueError("kind 'arrays' needs 'vertices' and 'faces'")
        return self


class Transform(_Strict):
    translate: Vec3 = (0.0, 0.0, 0.0)
    rotate_axis: Vec3 = (0.0, 1.0, 0.0)
    rotate_deg: float = 0.0
    scale: Vec3 = (1.0, 1.0, 1.0)

    _axis = field_validator("rotate_axis")(_nonzero)

    @field_validator("scale")
    @classmethod
    def _scale(cls, v):
        if not np.all(np.asarray(v, float)):
            raise ValueError("a zero scale component flattens the object to nothing")
        return v


class Motion(_Strict):
    velocity: Vec3 = (0.0, 0.0, 0.0)      # world units per frame
    spin_axis: Vec3 = (0.0, 1.0, 0.0)
    spin_deg: float = 0.0                 # degrees per frame about the object's origin

    _axis = field_validator("spin_axis")(_nonzero)


class SceneObject(_Strict):
    name: str
    mesh: MeshSpec
    material: Material = Material()
    transform: Transform = Transform()
    motion: Motion = Motion()

    @model_validator(mode="after")
    def _check(self):
        if self.mesh.kind == "gltf" and "material" in self.model_fields_set:
            raise ValueError("a glTF object takes its materials from the file; remove 'material'")
        return self


class DirectionalLight(_Strict):
    type: Literal["directional"] = "directional"
    direction: Vec3                       # direction the light travels
    intensity: RGB = (1.0, 1.0, 1.0)

    _direction = field_validator("direction")(_nonzero)


class PointLight(_Strict):
    type: Literal["point"] = "point"
    position: Vec3
    intensity: RGB = (1.0, 1.0, 1.0)      # irradiance at distance 1 (falls off as 1/d^2)


Light = Annotated[Union[DirectionalLight, PointLight], Field(discriminator="type")]


# The largest image side anything here renders (raster.limits holds the reason and the memory check).
MAX_SIDE = 8192
_Side = Annotated[int, Field(ge=8, le=MAX_SIDE)]


class Resolution(_Strict):
    quick: tuple[_Side, _Side] = (320, 180)
    full: tuple[_Side, _Side] = (1600, 900)


class Scene(_Strict):
    name: str
    description: str = ""
    stresses: str = ""                    # what the scene is meant to stress
    transport: Literal[TRANSPORTS] = "direct"
    frames: int = Field(1, ge=1)
    resolution: Resolution = Resolution()
    camera: Optional[Camera] = None       # may be left out when a glTF object supplies one
    objects: tuple[SceneObject, ...]
    lights: tuple[Light, ...] = ()
    ambient: RGB = (0.0, 0.0, 0.0)
    background: RGB = (0.0, 0.0, 0.0)
    path_max_depth: int = Field(8, ge=2)  # transport 'path': Mitsuba's path tracer, bounces + 1

    @field_validator("objects")
    @classmethod
    def _objects(cls, v):
        if not v:
            raise ValueError("a scene needs at least one object")
        names = [o.name for o in v]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"duplicate object names: {sorted(dup)}")
        if len(v) > 65534:
            raise ValueError("at most 65534 objects")
        return v

    @model_validator(mode="after")
    def _check(self):
        if self.transport != "unlit" and not self.lights and not any(self.ambient):
            raise ValueError(f"transport {self.transport!r} needs lights or an ambient term")
        gltf_cams = [o.name for o in self.objects if o.mesh.kind == "gltf" and o.mesh.camera]
        if len(gltf_cams) > 1:
            raise ValueError(f"objects {gltf_cams} all set camera = true; at most one may")
        beyond = [o.name for o in self.objects if o.material.is_gltf_model or o.material.occlusion is not None
                  or o.material.emission_texture is not None]
        if self.transport == "path" and beyond:
            raise ValueError(f"transport 'path' (Mitsuba's path tracer) shades Lambert materials with constant "
                             f"emission only; objects {beyond[:3]} declare roughness, metallic or material maps: "
                             "use direct_shadows")
        c = self.camera
        if not gltf_cams and (c is None or c.position is None or c.target is None):
            raise ValueError("camera needs a position and a target (or a glTF object with camera = true)")
        return self

    def features(self) -> list[str]:
        """What the scene exercises, for listings and for choosing agreement scenes."""
        f = [self.transport]
        if any(o.material.texture is not None for o in self.objects):
            f.append("texture")
        if any(o.material.alpha is not None for o in self.objects):
            f.append("alpha_cutout")
        if any(o.material.is_gltf_model for o in self.objects):
            f.append("metallic_roughness")
        if any(o.material.normal_map is not None for o in self.objects):
            f.append("normal_map")
        if self.transport in ("direct_shadows", "path"):
            f.append("shadows")
        if any(any(o.motion.velocity) or o.motion.spin_deg for o in self.objects):
            f.append("moving_object")
        c = self.camera or Camera()
        if any(c.velocity) or any(c.target_velocity):
            f.append("moving_camera")
        if c.cuts:
            f.append("camera_cut")
        return f
