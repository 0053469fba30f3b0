"""Surface texture for the static boxes of a world (walls, floor, furniture), no rclpy.

The shipped worlds are flat-shaded: a camera sees a plain colour on every wall, as no real
building looks, and feature-based localisation (ORB, place recognition) finds almost nothing
to track. With ``SimConfig(textures=True)`` static boxes are drawn textured:

- walls, doors, stairs: one texture per box, as long and high as the box at ``PX_PER_M`` (no
  repeats along a wall: repeated patterns would make every corridor the same place to a place
  recogniser): plaster — multi-scale noise, ±``WALL_CONTRAST`` of the colour — with notices at
  eye level (framed blocks of print, one per ~2.5 m), as corridors have signs and posters;
- floor: tiles — a 0.5 m grid of grout lines over mottled noise, repeating every ``TILE_M``;
- everything else: mottled noise, ±``OTHER_CONTRAST``, repeating every ``TILE_M``.

Noise is seeded by the box's place and size: same world, same textures. The texture multiplies
the part's colour, so classes keep their colours and labels are unchanged. PyBullet's EGL and
tiny renderers only apply a texture that a mesh's material names (``map_Kd``);
``loadTexture`` + ``changeVisualShape`` leaves the EGL renderer's default, and meshes created from
vertex lists are not drawn by the EGL plugin. So each textured box is a Wavefront OBJ with
metric texture coordinates, an MTL and a JPEG, written once into the cache folder
(``$RASPV_CACHE_DIR/sim_textures``) and loaded by file name.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import cv2
import numpy as np

PX_PER_M = 128               # wall texture resolution (detail down to ~2 cm)
MAX_PX = 4096                # longest wall texture side
TILE_M = 2.0                 # repeat of floor and furniture textures [m]
TILE_PX = 256
FLOOR_TILE_M = 0.5           # floor tile size (grout grid) [m]
WALL_CONTRAST = 0.18         # ± relative brightness of wall plaster
OTHER_CONTRAST = 0.15
NOTICE_EVERY_M = 2.5         # one notice per this much wall
STRUCTURE = frozenset({"wall", "door", "stairs"})


def cache_dir() -> Path:
    base = os.environ.get("RASPV_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "raspv")
    path = Path(base) / "sim_textures"
    path.mkdir(parents=True, exist_ok=True)
    return path


def periodic_noise(shape: int | tuple[int, int], seed: int,
                   wavelengths_px: tuple[float, ...] = (128, 64, 32, 16, 8, 4, 2)) -> np.ndarray:
    """Seamless (periodic) noise in [0, 1] of ``shape`` (rows, cols): white noise low-passed in
    the Fourier domain at several wavelengths [px], so a texture tiles without seams."""
    rows, cols = (shape, shape) if isinstance(shape, int) else shape
    rng = np.random.default_rng(seed)
    radius = np.hypot(np.fft.fftfreq(rows)[:, None], np.fft.fftfreq(cols)[None, :])     # cycles per px
    out = np.zeros((rows, cols))
    for wl in wavelengths_px:
        white = np.fft.fft2(rng.standard_normal((rows, cols)))
        layer = np.real(np.fft.ifft2(white * np.exp(-(radius * wl) ** 2)))
        out += layer / (layer.std() + 1e-12) * (wl / 128.0) ** 0.25
    out -= out.min()
    return out / max(out.max(), 1e-12)


def texture_image(kind: str, color: tuple[float, float, float], seed: int = 0,
                  size_m: tuple[float, float] | None = None) -> np.ndarray:
    """(rows, cols, 3) uint8 RGB texture of ``kind`` ("wall", "floor", "other") tinted by
    ``color`` (RGB in [0, 1]). A wall's spans ``size_m`` (length, height) [m] at ``PX_PER_M``;
    the others are ``TILE_PX`` square, one ``TILE_M`` repeat."""
    if kind == "wall":
        length, height = size_m or (TILE_M, TILE_M)
        shape = (min(MAX_PX, max(8, int(round(height * PX_PER_M)))), min(MAX_PX, max(8, int(round(length * PX_PER_M)))))
    else:
        shape = (TILE_PX, TILE_PX)
    n = periodic_noise(shape, seed)
    if kind == "floor":
        shade = 1.0 + OTHER_CONTRAST * (2 * n - 1)
        per_tile = int(round(TILE_PX * FLOOR_TILE_M / TILE_M))
        width = max(1, TILE_PX // 128)
        for k in range(0, TILE_PX, per_tile):
            shade[k:k + width, :] *= 0.55
            shade[:, k:k + width] *= 0.55
    else:
        shade = 1.0 + (WALL_CONTRAST if kind == "wall" else OTHER_CONTRAST) * (2 * n - 1)
    rgb = np.clip(np.asarray(color, dtype=float)[None, None, :] * shade[:, :, None], 0.0, 1.0)
    if kind == "wall":
        _add_notices(rgb, np.random.default_rng(seed + 7919), shape[1] / PX_PER_M)
    return (rgb * 255 + 0.5).astype(np.uint8)


def _add_notices(rgb: np.ndarray, rng: np.random.Generator, length_m: float) -> None:
    """Notices on a wall texture (in place): one per ``NOTICE_EVERY_M`` of wall, 20-50 cm, with
    their centres 1.0-1.7 m above the floor: a frame and a block pattern of printed matter."""
    rows, cols = rgb.shape[:2]
    height_m = rows / PX_PER_M
    for _ in range(max(1, int(round(length_m / NOTICE_EVERY_M)))):
        w, h = (rng.uniform(0.2, 0.5, 2) * PX_PER_M).astype(int)
        if w >= cols or h >= rows or height_m < 1.2:
            continue
        x = int(rng.integers(0, cols - w))
        centre = min(rng.uniform(1.0, 1.7), height_m - h / PX_PER_M)     # [m] above the floor
        top = max(0, rows - int(round(centre * PX_PER_M)) - h // 2)      # image row 0 is the top (v = 1)
        block = np.ones((h, w, 3)) * rng.uniform(0.75, 1.0, 3)
        cells = rng.integers(3, 9, 2)
        pattern = cv2.resize((rng.random((cells[1], cells[0])) < 0.45).astype(np.uint8), (w, h),
                             interpolation=cv2.INTER_NEAREST).astype(bool)
        block[pattern] = rng.uniform(0.0, 0.6, 3)
        border = max(2, w // 30)
        block[:border], block[-border:], block[:, :border], block[:, -border:] = 0.1, 0.1, 0.1, 0.1
        rgb[top:top + h, x:x + w] = block[:rgb.shape[0] - top]


def kind_of(cls: str) -> str:
    return "floor" if cls == "floor" else "wall" if cls in STRUCTURE else "other"


def _box_faces(size: tuple[float, float, float]):
    sx, sy, sz = size
    # (normal, u axis, v axis, half-extent along normal, extent along u, extent along v)
    return [((1, 0, 0), (0, 1, 0), (0, 0, 1), sx / 2, sy, sz), ((-1, 0, 0), (0, -1, 0), (0, 0, 1), sx / 2, sy, sz),
            ((0, 1, 0), (-1, 0, 0), (0, 0, 1), sy / 2, sx, sz), ((0, -1, 0), (1, 0, 0), (0, 0, 1), sy / 2, sx, sz),
            ((0, 0, 1), (1, 0, 0), (0, 1, 0), sz / 2, sx, sy), ((0, 0, -1), (-1, 0, 0), (0, 1, 0), sz / 2, sx, sy)]


def box_obj_text(size: tuple[float, float, float], material: str, mtl_file: str,
                 tile: tuple[float, float] = (TILE_M, TILE_M)) -> str:
    """A box of full extents ``size`` [m] centred at the origin as OBJ text; texture coordinates
    are metres along each face divided by ``tile`` (u, v) [m]: the texture spans that much."""
    lines = [f"mtllib {mtl_file}", f"usemtl {material}"]
    verts, uvs, normals, faces = [], [], [], []
    for n, u, v, d, su, sv in _box_faces(size):
        n, u, v = np.array(n, float), np.array(u, float), np.array(v, float)
        base = len(verts)
        for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            verts.append(n * d + u * a * su / 2 + v * b * sv / 2)
            uvs.append(((a + 1) / 2 * su / tile[0], (b + 1) / 2 * sv / tile[1]))
            normals.append(n)
        faces += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    lines += [f"v {p[0]:.5f} {p[1]:.5f} {p[2]:.5f}" for p in verts]
    lines += [f"vt {t[0]:.5f} {t[1]:.5f}" for t in uvs]
    lines += [f"vn {q[0]:.0f} {q[1]:.0f} {q[2]:.0f}" for q in normals]
    lines += ["f " + " ".join(f"{i + 1}/{i + 1}/{i + 1}" for i in face) for face in faces]
    return "\n".join(lines) + "\n"


def part_seed(position: tuple[float, float, float], size: tuple[float, float, float]) -> int:
    """A texture seed from where a part stands (cm) and its size: same world, same textures."""
    key = repr((tuple(int(round(p * 100)) for p in position), tuple(int(round(s * 100)) for s in size)))
    return int.from_bytes(hashlib.sha1(key.encode()).digest()[:4], "little")


def textured_box_obj(size: tuple[float, float, float], cls: str, color: tuple[float, float, float],
                     seed: int = 0) -> Path:
    """Path of an OBJ drawing a box of ``size`` [m] with the texture of ``cls`` tinted ``color``
    from noise ``seed`` (written into the cache folder on first use; later calls reuse the files).
    A wall's texture spans its longer horizontal side and its height; other kinds repeat."""
    kind = kind_of(cls)
    if kind == "wall":
        size_m = (max(size[0], size[1]), size[2])
        tile = size_m
    else:
        size_m, tile = None, (TILE_M, TILE_M)
    tex_key = hashlib.sha1(repr((kind, tuple(round(c, 4) for c in color), seed, size_m, PX_PER_M, TILE_PX)).encode()
                           ).hexdigest()[:12]
    box_key = hashlib.sha1(repr((tuple(round(s, 5) for s in size), tex_key, tile)).encode()).hexdigest()[:12]
    folder = cache_dir()
    image = folder / f"tex_{tex_key}.jpg"
    if not image.exists():
        bgr = texture_image(kind, color, seed, size_m)[:, :, ::-1]
        _atomic_write_bytes(image, cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 92])[1].tobytes())
    mtl = folder / f"tex_{tex_key}.mtl"
    if not mtl.exists():
        _atomic_write_bytes(mtl, f"newmtl m_{tex_key}\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nmap_Kd {image.name}\n".encode())
    obj = folder / f"box_{box_key}.obj"
    if not obj.exists():
        _atomic_write_bytes(obj, box_obj_text(size, f"m_{tex_key}", mtl.name, tile).encode())
    return obj


def _atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write via a temporary file and rename, so a process reading the cache (a parallel sweep)
    never sees half a file."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)
