"""A glTF 2.0 file's JSON and binary buffers (.gltf with external or data-URI buffers, .glb):
accessors (normalised, sparse), buffer views and images, each checked as it is read."""
from __future__ import annotations

import base64
import hashlib
import io
import json
import os
import stat
import struct
import urllib.parse

import numpy as np

_COMPONENT = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
# Dividers of the glTF spec's normalised integers (signed ones clamp at -1).
_NORM = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}
_MODES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP"}
_WRAP = {33071: "CLAMP_TO_EDGE", 33648: "MIRRORED_REPEAT"}
_LINEAR = {9729, 9985, 9986, 9987}
# Extensions whose content is read, or which change nothing the study renders.
SUPPORTED_EXTENSIONS = {"KHR_mesh_quantization", "KHR_materials_emissive_strength", "EXT_texture_webp"}
# Caps on what one file may make this process read: a buffer's declared byteLength (glTF's own
# limit is 2**53 - 1), an image file named by uri, and the .gltf/.glb itself.
MAX_BUFFER_BYTES = 2 ** 31
MAX_IMAGE_BYTES = 2 ** 28
MAX_FILE_BYTES = 2 ** 31 + 2 ** 20
_REMOTE = {"http", "https", "ftp", "ftps", "s3", "gs"}


class _Malformed(Exception):
    """A structural problem; `where` is the JSON path inside the glTF file."""

    def __init__(self, where: str, msg: str):
        super().__init__(f"{where}: {msg}")



class _Container:
    """The JSON and the binary buffers of one glTF file."""

    def __init__(self, full: str):
        self.full, self.dir = full, os.path.dirname(full)
        self.digests: list[str] = []
        size = os.stat(full).st_size
        if size > MAX_FILE_BYTES:
            raise _Malformed("(file)", f"{size} bytes, more than the {MAX_FILE_BYTES} a glTF file may have here")
        with open(full, "rb") as fh:
            raw = fh.read(MAX_FILE_BYTES + 1)
        if len(raw) > MAX_FILE_BYTES:
            raise _Malformed("(file)", f"more than the {MAX_FILE_BYTES} bytes a glTF file may have here")
        self.digests.append(hashlib.sha256(raw).hexdigest())
        bin_chunk = None
        if raw[:4] == b"glTF":
            self.json, bin_chunk = self._glb(raw)
        else:
            try:
                self.json = json.loads(raw.decode("utf-8-sig"))
            except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                raise _Malformed("(file)", f"neither a GLB nor glTF JSON: {exc}") from None
        if not isinstance(self.json, dict):
            raise _Malformed("(top level)", "the JSON is not an object")
        version = str(self.json.get("asset", {}).get("version", ""))
        if not version.startswith("2."):
            raise _Malformed("asset.version", f"only glTF 2.x is supported, got {version!r}")
        self.buffers = []
        for i, b in enumerate(self.json.get("buffers", [])):
            declared = b.get("byteLength")
            if not isinstance(declared, int) or isinstance(declared, bool) or not 1 <= declared <= MAX_BUFFER_BYTES:
                raise _Malformed(f"buffers[{i}].byteLength", f"must be a whole number in 1..{MAX_BUFFER_BYTES}, "
                                 f"got {declared!r}")
            if "uri" in b:
                # a file may be padded past its byteLength: only the declared bytes are read
                data = self.uri_bytes(b["uri"], f"buffers[{i}].uri", limit=declared, truncate=True)
            elif i == 0 and bin_chunk is not None:
                data = bin_chunk
            else:
                raise _Malformed(f"buffers[{i}]", "has no uri and is not the GLB's binary chunk")
            if len(data) < b.get("byteLength", 0):
                raise _Malformed(f"buffers[{i}]", f"byteLength {b['byteLength']} but {len(data)} bytes")
            self.buffers.append(data)

    @staticmethod
    def _glb(raw: bytes):
        if len(raw) < 20:
            raise _Malformed("(GLB header)", f"file of {len(raw)} bytes is truncated")
        _, version, length = struct.unpack_from("<4sII", raw)
        if version != 2:
            raise _Malformed("(GLB header)", f"GLB version {version}, only 2 is supported")
        if length > len(raw):
            raise _Malformed("(GLB header)", f"declares {length} bytes, the file has {len(raw)}")
        pos, doc, binary = 12, None, None
        while pos + 8 <= length:
            size, kind = struct.unpack_from("<II", raw, pos)
            body = raw[pos + 8:pos + 8 + size]
            if len(body) != size:
                raise _Malformed("(GLB chunk)", f"chunk at byte {pos} is truncated")
            if kind == 0x4E4F534A and doc is None:
                try:
                    doc = json.loads(body.decode("utf-8"))
                except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                    raise _Malformed("(GLB JSON chunk)", f"cannot parse: {exc}") from None
            elif kind == 0x004E4942 and binary is None:
                binary = body
            pos += 8 + size + (-size % 4)
        if doc is None:
            raise _Malformed("(GLB)", "has no JSON chunk")
        return doc, binary

    def uri_bytes(self, uri, where: str, limit: int | None = None, truncate: bool = False) -> bytes:
        """The bytes a buffer's or image's `uri` names: a `data:` URI, or a relative path that
        resolves (symbolic links followed) to a regular file inside the glTF file's folder, at most
        `limit` bytes of it (default MAX_IMAGE_BYTES; `truncate`: its first `limit` bytes, else a
        larger file is refused). Anything else is refused by name; the file's content is never quoted."""
        limit = MAX_IMAGE_BYTES if limit is None else limit
        if not isinstance(uri, str):
            raise _Malformed(where, f"uri must be a string, got {type(uri).__name__}")
        if uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            try:
                return base64.b64decode(payload, validate=True) if head.endswith(";base64") \
                    else urllib.parse.unquote_to_bytes(payload)
            except ValueError as exc:
                raise _Malformed(where, f"bad data URI: {exc}") from None
        scheme = urllib.parse.urlsplit(uri).scheme.lower()
        if scheme in _REMOTE:
            raise _Malformed(where, f"remote URIs are not fetched: {uri}")
        if scheme:
            raise _Malformed(where, f"URI scheme {scheme!r} is not read ({uri}); give a path relative to "
                             "the glTF file's folder or a data: URI")
        rel = urllib.parse.unquote(uri)
        if "\0" in rel:
            raise _Malformed(where, f"uri {uri!r} holds a NUL character")
        if os.path.isabs(rel):
            raise _Malformed(where, f"absolute paths are not read ({uri}); give a path relative to "
                             "the glTF file's folder")
        folder = os.path.realpath(self.dir)
        path = os.path.realpath(os.path.join(folder, rel))
        if os.path.commonpath([folder, path]) != folder:
            raise _Malformed(where, f"uri {uri!r} resolves outside the glTF file's folder {folder}")
        try:
            st = os.stat(path)
        except FileNotFoundError:
            raise _Malformed(where, f"file not found: {path}") from None
        except OSError as exc:
            raise _Malformed(where, f"cannot read {path}: {exc.strerror}") from None
        if not stat.S_ISREG(st.st_mode):
            raise _Malformed(where, f"{path} is not a regular file")
        if st.st_size > limit and not truncate:
            raise _Malformed(where, f"{path} has {st.st_size} bytes, more than the {limit} a glTF "
                             "file may name here")
        try:
            with open(path, "rb") as fh:
                data = fh.read(limit + 1)
        except OSError as exc:
            raise _Malformed(where, f"cannot read {path}: {exc.strerror}") from None
        if truncate:
            data = data[:limit]
        elif len(data) > limit:             # a file that grew since its stat
            raise _Malformed(where, f"{path} has more than the {limit} bytes a glTF file may name here")
        self.digests.append(hashlib.sha256(data).hexdigest())
        return data

    def item(self, kind: str, index, where: str) -> dict:
        items = self.json.get(kind, [])
        if not isinstance(index, int) or not 0 <= index < len(items):
            raise _Malformed(where, f"{kind} index {index!r} out of range (the file has {len(items)})")
        return items[index]

    def view(self, index: int, where: str) -> tuple[bytes, int | None]:
        v = self.item("bufferViews", index, where)
        self.item("buffers", v["buffer"], f"bufferViews[{index}].buffer")
        buf = self.buffers[v["buffer"]]
        start, length = v.get("byteOffset", 0), v["byteLength"]
        if start + length > len(buf):
            raise _Malformed(f"bufferViews[{index}]", f"bytes {start}..{start + length} past the end "
                             f"of buffer {v['buffer']} ({len(buf)} bytes)")
        return buf[start:start + length], v.get("byteStride")

    def _read(self, view: int, offset: int, count: int, comp: int, width: int, where: str) -> np.ndarray:
        if comp not in _COMPONENT:
            raise _Malformed(where, f"componentType {comp} is not a glTF component type")
        dt = np.dtype(_COMPONENT[comp])
        data, stride = self.view(view, where)
        stride = stride or dt.itemsize * width
        need = offset + (count - 1) * stride + dt.itemsize * width if count else 0
        if need > len(data):
            raise _Malformed(where, f"{count} elements need {need} bytes of bufferView {view}, "
                             f"which has {len(data)}")
        if count == 0:
            return np.zeros((0, width), dt)
        return np.ndarray((count, width), dt, data, offset, (stride, dt.itemsize)).copy()

    def accessor(self, index, where: str, widths: tuple[int, ...]) -> np.ndarray:
        """(count, width) array; normalised integers become floats as the spec defines them."""
        a = self.item("accessors", index, where)
        where = f"accessors[{index}]"
        width = _WIDTH.get(a.get("type"))
        if width not in widths:
            raise _Malformed(where, f"type {a.get('type')!r} where {widths} components are expected")
        comp, count = a["componentType"], a["count"]
        if "bufferView" in a:
            out = self._read(a["bufferView"], a.get("byteOffset", 0), count, comp, width, where)
        else:
            out = np.zeros((count, width), np.dtype(_COMPONENT.get(comp, "<f4")))
        if "sparse" in a:
            s = a["sparse"]
            idx = self._read(s["indices"]["bufferView"], s["indices"].get("byteOffset", 0), s["count"],
                             s["indices"]["componentType"], 1, f"{where}.sparse.indices")[:, 0]
            if len(idx) and idx.max() >= count:
                raise _Malformed(f"{where}.sparse.indices", f"index {int(idx.max())} >= count {count}")
            out[idx.astype(np.int64)] = self._read(s["values"]["bufferView"], s["values"].get("byteOffset", 0),
                                                   s["count"], comp, width, f"{where}.sparse.values")
        if a.get("normalized") and comp in _NORM:
            return np.maximum(out.astype(np.float64) / _NORM[comp], -1.0)
        return out

    def image_rgba(self, index: int, where: str) -> np.ndarray:
        from PIL import Image
        img = self.item("images", index, where)
        where = f"images[{index}]"
        if "uri" in img:
            data = self.uri_bytes(img["uri"], f"{where}.uri")
        elif "bufferView" in img:
            data = self.view(img["bufferView"], f"{where}.bufferView")[0]
        else:
            raise _Malformed(where, "has neither uri nor bufferView")
        try:
            with Image.open(io.BytesIO(data)) as im:
                return np.asarray(im.convert("RGBA"))
        except Exception as exc:   # Pillow raises several types for undecodable data
            raise _Malformed(where, f"cannot decode the image: {exc}") from None
