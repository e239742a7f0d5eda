"""Images the shaders sample, made procedurally here, or read from the user's files.

All generated images are uint8 RGB arrays, row 0 at the top.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import RenderError

CUBE_FACES = ("posx", "negx", "posy", "negy", "posz", "negz")


def plaid_texture(size: int = 512) -> np.ndarray:
    """A woven tartan: crossing bands of warp and weft with a twill diagonal."""
    y, x = np.mgrid[0:size, 0:size] / size
    palette = np.array([[0.55, 0.10, 0.12], [0.10, 0.22, 0.40], [0.12, 0.35, 0.20], [0.85, 0.75, 0.45]])

    def bands(t: np.ndarray) -> np.ndarray:
        s = (t * 8.0) % 1.0
        return np.select([s < 0.45, s < 0.6, s < 0.9], [0, 1, 2], 3)

    warp = palette[bands(x)]
    weft = palette[bands(y)]
    twill = (((x + y) * size / 4.0).astype(int) % 2).astype(float)[..., None]
    img = 0.5 * (warp + weft) * (0.82 + 0.18 * twill)
    return (np.clip(img, 0, 1) * 255).astype(np.uint8)


def weave_height(size: int = 512, threads: int = 24) -> np.ndarray:
    """Height map of a plain weave: threads rising and dipping over each other."""
    y, x = np.mgrid[0:size, 0:size] / size * threads
    over = (np.floor(x) + np.floor(y)) % 2
    warp = np.abs(np.sin(np.pi * x)) ** 0.5
    weft = np.abs(np.sin(np.pi * y)) ** 0.5
    h = np.where(over == 0, 0.35 + 0.65 * warp * (0.6 + 0.4 * weft), 0.35 + 0.65 * weft * (0.6 + 0.4 * warp))
    h = (h - h.min()) / (h.max() - h.min())
    return np.repeat((h * 255).astype(np.uint8)[..., None], 3, axis=2)


def _face_directions(face: str, size: int) -> np.ndarray:
    """World direction of each texel of a cube face (OpenGL cube-map convention)."""
    s = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    tc, sc = np.meshgrid(s, s, indexing="ij")  # row index -> t, column -> s
    one = np.ones_like(sc)
    d = {
        "posx": (one, -tc, -sc), "negx": (-one, -tc, sc),
        "posy": (sc, one, tc), "negy": (sc, -one, -tc),
        "posz": (sc, -tc, one), "negz": (-sc, -tc, -one),
    }[face]
    v = np.stack(d, axis=-1)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def sky_environment(size: int = 256) -> dict[str, np.ndarray]:
    """Six cube faces of a sky-and-ground world: a blue gradient sky with a sun and
    a warm horizon above a checkered ground, so reflections read clearly."""
    sun = np.array([0.4, 0.55, 0.73])
    sun /= np.linalg.norm(sun)
    faces = {}
    for face in CUBE_FACES:
        d = _face_directions(face, size)
        up = d[..., 1:2]
        zenith = np.array([0.18, 0.38, 0.78])
        horizon = np.array([0.95, 0.80, 0.62])
        t = np.clip(up, 0, 1) ** 0.6
        sky = horizon * (1 - t) + zenith * t
        glow = np.clip(d @ sun, 0, 1)[..., None]
        sky = sky + np.array([1.0, 0.9, 0.7]) * (glow ** 200 * 2.0 + glow ** 8 * 0.25)
        # ground: project onto y = -1 and checker it
        g = np.where(up < -1e-3, up, -1e-3)
        gx, gz = d[..., 0] / -g[..., 0], d[..., 2] / -g[..., 0]
        check = ((np.floor(gx * 2) + np.floor(gz * 2)) % 2)[..., None]
        fade = np.clip(-up * 4, 0, 1)
        ground = (np.array([0.30, 0.27, 0.22]) + 0.25 * check) * fade + horizon * 0.6 * (1 - fade)
        img = np.where(up >= 0, sky, ground)
        faces[face] = (np.clip(img, 0, 1) * 255).astype(np.uint8)
    return faces


def read_image(path: str | Path, what: str) -> np.ndarray:
    """RGB uint8 array of an image file, or a RenderError naming the file."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("RGB"))
    except FileNotFoundError:
        raise RenderError(f"{path}: no such {what} image") from None
    except (UnidentifiedImageError, OSError) as exc:
        raise RenderError(f"{path}: cannot read the {what} image ({exc})") from None


def read_cubemap(folder: str | Path) -> dict[str, np.ndarray]:
    """Six faces posx..negz (any image extension) from a folder, all the same square size."""
    folder = Path(folder)
    if not folder.is_dir():
        raise RenderError(f"{folder}: expected a folder with posx, negx, posy, negy, posz, negz images")
    faces = {}
    for face in CUBE_FACES:
        found = sorted(folder.glob(face + ".*"))
        if not found:
            raise RenderError(f"{folder}: missing cube face {face} (expected {face}.png or similar)")
        faces[face] = read_image(found[0], f"cube face {face}")
    shapes = {img.shape for img in faces.values()}
    if len(shapes) != 1 or next(iter(shapes))[0] != next(iter(shapes))[1]:
        raise RenderError(f"{folder}: cube faces must be square and all the same size, got {sorted(shapes)}")
    return faces


TEXTURE_UNITS = (1, 2, 3, 4)


def read_texture_folder(folder: str | Path) -> tuple[dict[int, np.ndarray], dict[str, np.ndarray] | None]:
    """What CS184 loads from a ``textures/`` folder: ``texture_1.png`` .. ``texture_4.png``
    (the units ``u_texture_1..4``; any image extension, ``.png`` first) and the cube map
    in ``cube/`` (posx .. negz). Each file may be missing; a folder that is not there is
    an error."""
    folder = Path(folder)
    if not folder.is_dir():
        raise RenderError(f"{folder}: expected a textures folder (texture_1.png .. texture_4.png, cube/)")
    units = {}
    for unit in TEXTURE_UNITS:
        found = sorted(folder.glob(f"texture_{unit}.*"), key=lambda p: (p.suffix.lower() != ".png", p.name))
        if found:
            units[unit] = read_image(found[0], f"texture_{unit}")
    cube = folder / "cube"
    return units, (read_cubemap(cube) if cube.is_dir() else None)
