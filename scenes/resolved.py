"""A scene with its assets built: meshes, textures, per-frame poses and a content hash."""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from . import meshes
from .camera import CameraState, look_at
from .description import Camera, Scene, Texture
from .meshes import MeshData, SceneError

PROFILES = ("quick", "full")


def _rotation(axis, deg) -> np.ndarray:
    a = np.asarray(axis, float)
    n = np.linalg.norm(a)
    if n == 0:
        if deg:
            raise SceneError("rotation axis is the zero vector")
        return np.eye(3)
    x, y, z = a / n
    t = np.radians(deg)
    c, s, C = np.cos(t), np.sin(t), 1 - np.cos(t)
    return np.array([[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
                     [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
                     [z * x * C - y * s, z * y * C + x * s, c + z * z * C]])


# Material texture roles besides the base colour and the cut-out: (field, colour-encoded file?)
MAP_ROLES = (("metallic_roughness", False), ("normal_map", False), ("emission_texture", True),
             ("occlusion", False))


def build_texture(tex: Texture, where: str, base_dir: str | None, srgb: bool = True) -> np.ndarray:
    """(H, W, C) float32 linear values; an image file is sRGB-decoded where `srgb` (colour), read
    as stored otherwise (data: normals, metallic-roughness, occlusion)."""
    if tex.kind == "checker":
        n = tex.squares
        i, j = np.meshgrid(np.arange(n), np.arange(n))
        mask = ((i + j) % 2 == 0)[..., None]
        return np.where(mask, tex.color_a, tex.color_b).astype(np.float32)
    if tex.kind == "array":
        d = np.asarray(tex.data, np.float32)
        return d[..., None] if d.ndim == 2 else d
    import colour
    from PIL import Image
    full = tex.path if os.path.isabs(tex.path) or base_dir is None else os.path.join(base_dir, tex.path)
    if not os.path.isfile(full):
        raise SceneError(f"{where}: texture file not found: {full}")
    try:
        with Image.open(full) as raw:
            raw.load()
            # a float image (TIFF mode F) would turn NaN/Inf into arbitrary 8-bit values
            if raw.mode.startswith(("F", "I")):
                bad = ~np.isfinite(np.asarray(raw, np.float64))
                if bad.any():
                    r, c = np.argwhere(bad)[0]
                    raise SceneError(f"{where}: texture {full} has {int(bad.sum())} NaN/Inf texel(s) "
                                     f"(first at row {r}, column {c})")
            img = np.asarray(raw.convert("RGB"), np.float32) / 255.0
    except SceneError:
        raise
    except Exception as exc:
        raise SceneError(f"{where}: cannot read texture {full}: {exc}") from exc
    # Row 0 of our textures is v = 0 (bottom of the image as usually authored).
    if not srgb:
        return np.ascontiguousarray(img[::-1], np.float32)
    return colour.cctf_decoding(img[::-1], function="sRGB").astype(np.float32)


def _check_normal_map(a: np.ndarray, where: str) -> None:
    """A texel whose decoded vector (2 c - 1) has no length has no direction to shade with."""
    if a.shape[-1] < 3:
        raise SceneError(f"{where}: a normal map needs 3 channels, got {a.shape[-1]}")
    zero = np.linalg.norm(2.0 * a[..., :3].astype(np.float64) - 1.0, axis=-1) < 1e-6
    if zero.any():
        r, c = np.argwhere(zero)[0]
        raise SceneError(f"{where}: {int(zero.sum())} texel(s) decode to a zero-length normal "
                         f"(first at row {r}, column {c}: {a[r, c, :3].tolist()})")


@dataclass
class ResolvedScene:
    desc: Scene
    base_dir: str | None = None
    source: str | None = None        # the scene file, named in errors and warnings
    meshes: list[MeshData] = field(init=False)
    textures: list[np.ndarray | None] = field(init=False)   # albedo texture per object
    alphas: list[np.ndarray | None] = field(init=False)     # alpha texture per object (H, W)
    # per object: the textures of MAP_ROLES it declares, by field name ((H, W, C) float32 linear)
    maps: list[dict[str, np.ndarray]] = field(init=False)
    # sha256 of asset files hashed as files (glTF and the buffers and images it names)
    asset_digests: list[str] = field(init=False)

    def __post_init__(self):
        self.meshes, self.textures, self.alphas, self.asset_digests, self.maps = [], [], [], [], []
        pre = f"{self.source}: " if self.source else ""
        prebuilt = self._expand_gltf(pre)
        # One array per texture description: objects that share one (a glTF material used by
        # several primitives) share the decoded data.
        built: dict[int, np.ndarray] = {}
        checked: set[int] = set()

        def tex(t: Texture, where: str, alpha: bool, srgb: bool = True) -> np.ndarray:
            if id(t) not in built:
                a = build_texture(t, where, self.base_dir, srgb)
                built[id(t)] = a.mean(axis=-1) if alpha else a
            return built[id(t)]

        for i, obj in enumerate(self.desc.objects):
            where = f"{pre}objects[{i}] ({obj.name!r})"
            m = prebuilt[i] if i in prebuilt else meshes.build(obj.mesh, f"{where}.mesh", self.base_dir)
            mat = obj.material
            maps = {k: tex(getattr(mat, k), f"{where}.material.{k}", False, srgb)
                    for k, srgb in MAP_ROLES if getattr(mat, k) is not None}
            if (mat.texture is not None or mat.alpha is not None or maps) and m.uvs is None:
                raise SceneError(f"{where}.material: a texture needs UVs but the mesh has none")
            if "normal_map" in maps and id(maps["normal_map"]) not in checked:   # once per shared array
                _check_normal_map(maps["normal_map"], f"{where}.material.normal_map")
                checked.add(id(maps["normal_map"]))
            self.maps.append(maps)
            self.meshes.append(m)
            self.textures.append(None if mat.texture is None else
                                 tex(mat.texture, f"{where}.material.texture", False))
            self.alphas.append(None if mat.alpha is None else tex(mat.alpha, f"{where}.material.alpha", True))
        self._check_animation(pre)

    def _expand_gltf(self, pre: str) -> dict[int, MeshData]:
        """Replace every glTF object of the description by its primitives (scenes/gltf.py), and
        take its camera if asked to. Returns the already built meshes by new object index."""
        if not any(o.mesh.kind == "gltf" for o in self.desc.objects):
            return {}
        from . import gltf
        objects, prebuilt, cam, cam_pose, cam_verts = [], {}, None, None, []
        for i, obj in enumerate(self.desc.objects):
            if obj.mesh.kind != "gltf":
                objects.append(obj)
                continue
            g = gltf.read(obj, self.base_dir, f"{pre}objects[{i}] ({obj.name!r}).mesh")
            for o, m in zip(g.objects, g.meshes):
                prebuilt[len(objects)] = m
                objects.append(o)
            self.asset_digests += g.digests
            if g.camera is not None:
                cam, cam_pose = g.camera, self._base_pose(obj)
                cam_verts = [m.vertices for m in g.meshes]
        update: dict = {"objects": tuple(objects)}
        if cam is not None:
            update["camera"] = self._gltf_camera(cam, cam_pose, cam_verts, pre)
        try:
            self.desc = Scene.model_validate({**{k: getattr(self.desc, k) for k in type(self.desc).model_fields},
                                              **update})
        except ValueError as exc:   # e.g. an expanded object's name collides with another object
            raise SceneError(f"{pre}after expanding the glTF objects: {exc}") from None
        return prebuilt

    @staticmethod
    def _base_pose(obj) -> np.ndarray:
        m = np.eye(4)
        m[:3, :3] = _rotation(obj.transform.rotate_axis, obj.transform.rotate_deg) * \
            np.asarray(obj.transform.scale, float)
        m[:3, 3] = obj.transform.translate
        return m

    def _gltf_camera(self, cam: dict, pose: np.ndarray, verts: list[np.ndarray], pre: str) -> Camera:
        """The glTF camera under its object's transform; fields the scene file sets win."""
        pos = pose[:3, :3] @ cam["position"] + pose[:3, 3]
        fields = {"position": tuple(pos), "target": tuple(pose[:3, :3] @ cam["target"] + pose[:3, 3]),
                  "up": tuple(pose[:3, :3] @ cam["up"]), "yfov_deg": cam["yfov_deg"], "near": cam["near"]}
        if "far" in cam:
            fields["far"] = cam["far"]
        else:
            # An infinite projection: far just beyond the glTF's farthest bounding-box corner.
            world = np.concatenate(verts) @ pose[:3, :3].T + pose[:3, 3]
            lo, hi = world.min(axis=0), world.max(axis=0)
            corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            fields["far"] = float(max(np.linalg.norm(corners - pos, axis=1).max() * 1.01, 2 * cam["near"]))
        given = self.desc.camera
        if given is not None:
            fields.update({k: getattr(given, k) for k in given.model_fields_set})
        try:
            return Camera.model_validate(fields)
        except ValueError as exc:
            raise SceneError(f"{pre}camera (the glTF camera with the scene file's fields): {exc}") from None

    def _check_animation(self, pre: str) -> None:
        """Every frame must have a camera and finite object positions. The description validates
        single values; this catches their combination over time (a camera that moves onto its
        target, up parallel to the view, velocity * t overflowing) before anything renders."""
        for t in range(self.desc.frames):
            pos, tgt = self._camera_pos_target(t)
            f = tgt - pos
            if not np.all(np.isfinite(f)) or np.allclose(f, 0):
                raise SceneError(f"{pre}camera: at frame {t} position {tuple(pos)} and target "
                                 f"{tuple(tgt)} give no view direction")
            try:
                to_world = look_at(pos, tgt, self.desc.camera.up)
            except ValueError as exc:
                raise SceneError(f"{pre}camera: at frame {t}: {exc}") from None
            if not np.all(np.isfinite(to_world)):
                raise SceneError(f"{pre}camera: at frame {t} the pose is not finite")
        last = self.desc.frames - 1
        for i, obj in enumerate(self.desc.objects):
            for t in {0, last}:
                with np.errstate(over="ignore", invalid="ignore"):
                    finite = np.all(np.isfinite(self.world_vertices(i, t)))
                if not finite:
                    raise SceneError(f"{pre}objects[{i}] ({obj.name!r}): world positions overflow "
                                     f"at frame {t} (transform/motion too large)")

    @property
    def name(self) -> str:
        return self.desc.name

    def resolution(self, profile: str) -> tuple[int, int]:
        if profile not in PROFILES:
            raise SceneError(f"unknown profile {profile!r}; choose one of {PROFILES}")
        return tuple(getattr(self.desc.resolution, profile))

    # -- animation -------------------------------------------------------------------------
    def object_pose(self, i: int, t: int) -> np.ndarray:
        """Object-to-world 4x4 at frame t: base scale, rotation, translation, then the motion."""
        o = self.desc.objects[i]
        m = np.eye(4)
        rot = _rotation(o.motion.spin_axis, o.motion.spin_deg * t) @ \
            _rotation(o.transform.rotate_axis, o.transform.rotate_deg)
        m[:3, :3] = rot * np.asarray(o.transform.scale, float)
        m[:3, 3] = np.asarray(o.transform.translate, float) + np.asarray(o.motion.velocity, float) * t
        return m

    def world_vertices(self, i: int, t: int) -> np.ndarray:
        m = self.object_pose(i, t)
        return self.meshes[i].vertices @ m[:3, :3].T + m[:3, 3]

    def world_normals(self, i: int, t: int) -> np.ndarray | None:
        n = self.meshes[i].normals
        if n is None:
            return None
        w = n @ np.linalg.inv(self.object_pose(i, t)[:3, :3])   # inverse transpose, row vectors
        return w / np.linalg.norm(w, axis=1, keepdims=True)

    def world_tangents(self, i: int, t: int) -> np.ndarray | None:
        """(V, 4): the mesh's tangents under the pose at t, w flipped where the pose mirrors."""
        tg = self.meshes[i].tangents
        if tg is None:
            return None
        m = self.object_pose(i, t)[:3, :3]
        xyz = tg[:, :3] @ m.T
        xyz /= np.linalg.norm(xyz, axis=1, keepdims=True)
        return np.concatenate([xyz, tg[:, 3:] * np.sign(np.linalg.det(m))], 1)

    def is_static(self, i: int) -> bool:
        mo = self.desc.objects[i].motion
        return not any(mo.velocity) and not mo.spin_deg

    def _camera_pos_target(self, t: int) -> tuple[np.ndarray, np.ndarray]:
        c = self.desc.camera
        pos, tgt, t0 = np.asarray(c.position, float), np.asarray(c.target, float), 0
        for cut in sorted(c.cuts, key=lambda k: k.frame):
            if cut.frame <= t:
                pos, tgt, t0 = np.asarray(cut.position, float), np.asarray(cut.target, float), cut.frame
        dt = t - t0
        return pos + np.asarray(c.velocity, float) * dt, tgt + np.asarray(c.target_velocity, float) * dt

    def camera(self, t: int, width: int, height: int) -> CameraState:
        c = self.desc.camera
        pos, tgt = self._camera_pos_target(t)
        return CameraState(look_at(pos, tgt, c.up), c.yfov_deg, c.near, c.far, width, height)

    def is_cut(self, t: int) -> bool:
        """True where history from frame t-1 must not be used (first frame or a hard cut)."""
        return t == 0 or any(cut.frame == t for cut in self.desc.camera.cuts)

    # -- identity --------------------------------------------------------------------------
    @cached_property
    def content_hash(self) -> str:
        """Hash of everything that determines the images: description, mesh and texture data."""
        h = hashlib.sha256(json.dumps(self.desc.model_dump(mode="json"), sort_keys=True).encode())
        seen: dict[int, int] = {}
        for arrays in (self.meshes, self.textures, self.alphas):
            for a in arrays:
                parts = (a.vertices, a.faces, a.uvs, a.normals) if isinstance(a, MeshData) else (a,)
                if isinstance(a, MeshData) and a.tangents is not None:   # absent: hashes as before
                    parts += (a.tangents,)
                for p in parts:
                    if p is not None and self.asset_digests and id(p) in seen:
                        # A glTF material's texture, shared by its primitives, is hashed once
                        # (scenes without glTF objects keep the hash they always had).
                        h.update(f"={seen[id(p)]}".encode())
                        continue
                    if p is not None:
                        seen[id(p)] = len(seen)
                    h.update(b"-" if p is None else np.ascontiguousarray(p).tobytes())
        for i, maps in enumerate(self.maps):   # none in Lambert scenes: they keep their hash
            for k in sorted(maps):
                h.update(f"{i}.{k}".encode())
                if id(maps[k]) in seen:          # a glTF material's map, shared by its primitives
                    h.update(f"={seen[id(maps[k])]}".encode())
                    continue
                seen[id(maps[k])] = len(seen)
                h.update(np.ascontiguousarray(maps[k]).tobytes())
        for d in self.asset_digests:   # none without glTF objects: other scenes keep their hash
            h.update(d.encode())
        return h.hexdigest()[:16]
