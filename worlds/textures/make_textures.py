"""Make the warehouse's textures from noise and drawing, nothing downloaded (`make textures`).

Every image is seeded by its own name, so a run writes the same pixels again (the same bytes with
the same numpy, OpenCV and libjpeg; `tests/test_warehouse_textures.py` compares pixels with a
tolerance, which holds across versions).

Gazebo's box maps the whole image onto each face, and Gazebo multiplies the albedo map by the
material's diffuse colour. So the textures of surfaces with a colour of their own (concrete,
painted steel, cartons, paint) are light, mostly neutral detail maps, about 0.8 on average: the
SDF keeps its colour, which is also what TinyRenderer draws, and the map adds the detail that
visual SLAM needs at several scales (slab joints and stains at metres, aggregate and scratches
at millimetres). Signs carry their own colours on a white material.

Sizes follow the face they cover, about 4 mm a texel on the floor (1024² over a 4 m slab: a
pixel of the 120° cameras covers 3 mm of floor at 1 m and 15 mm at 5 m) and 2–5 mm elsewhere.
The floor is tiled in 4 m slabs (25 box visuals, two textures in a checkerboard) rather than one
20 m box with an 8192² image: 2 × 5.6 MB of GPU memory with mipmaps instead of 358 MB, the
same sharpness.

    python worlds/textures/make_textures.py [--out DIR]
"""

from __future__ import annotations

import argparse
import zlib
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

HERE = Path(__file__).resolve().parent
MODELS = HERE.parent / "models"
Image = npt.NDArray[np.float32]
"""H×W×3 RGB in 0..1 while drawing; written as 8-bit."""
FONT = cv2.FONT_HERSHEY_SIMPLEX
BOLD = cv2.FONT_HERSHEY_DUPLEX


def rng_for(name: str) -> np.random.Generator:
    """A generator seeded by the texture's name: each image reproducible on its own."""
    return np.random.default_rng(zlib.crc32(name.encode()))


def noise(rng: np.random.Generator, height: int, width: int, scales: tuple[int, ...]) -> Image:
    """Value noise summed over octaves: a random grid every `scale` texels, smoothly upsampled,
    each octave half the amplitude of the coarser one; zero mean, about unit spread."""
    total = np.zeros((height, width), np.float32)
    amplitude, weight = 1.0, 0.0
    for scale in sorted(scales, reverse=True):
        grid = rng.standard_normal((max(2, height // scale + 2), max(2, width // scale + 2))).astype(np.float32)
        up = cv2.resize(grid, (grid.shape[1] * scale, grid.shape[0] * scale), interpolation=cv2.INTER_CUBIC)
        total += amplitude * up[:height, :width]
        weight += amplitude**2
        amplitude *= 0.55
    return total / np.sqrt(weight)


def grey(value: npt.ArrayLike, tint: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> Image:
    """An RGB image from a grey level map, times a tint."""
    level = np.asarray(value, np.float32)
    return np.clip(level[..., None] * np.array(tint, np.float32), 0.0, 1.0)


def blotches(rng: np.random.Generator, image: Image, count: int, radius: tuple[int, int], depth: float) -> None:
    """Soft dark stains (oil, water, tyre rubber) of random size, darkening `image` by up to `depth`."""
    h, w = image.shape[:2]
    mask = np.zeros((h, w), np.float32)
    for _ in range(count):
        centre = (int(rng.integers(0, w)), int(rng.integers(0, h)))
        axes = (int(rng.integers(*radius)), int(rng.integers(*radius)))
        cv2.ellipse(mask, centre, axes, float(rng.uniform(0, 180)), 0, 360, float(rng.uniform(0.3, 1.0)), -1)
    mask = np.asarray(cv2.GaussianBlur(mask, (0, 0), radius[0] / 2), np.float32)
    image *= 1.0 - depth * np.clip(mask, 0, 1)[..., None]


def speckle(rng: np.random.Generator, image: Image, count: int, size: int, spread: float) -> None:
    """Small light and dark dots (aggregate in concrete, chips in paint)."""
    h, w = image.shape[:2]
    for _ in range(count):
        centre = (int(rng.integers(0, w)), int(rng.integers(0, h)))
        level = float(np.clip(rng.normal(0.78, spread), 0.2, 1.0))
        cv2.circle(image, centre, int(rng.integers(1, size + 1)), (level, level, level), -1, cv2.LINE_AA)


def scratches(rng: np.random.Generator, image: Image, count: int, length: int, level: float) -> None:
    """Thin straight marks at random angles (scuffs on paint and steel)."""
    h, w = image.shape[:2]
    for _ in range(count):
        x, y = float(rng.uniform(0, w)), float(rng.uniform(0, h))
        angle, size = float(rng.uniform(0, np.pi)), float(rng.uniform(0.2, 1.0)) * length
        end = (int(x + size * np.cos(angle)), int(y + size * np.sin(angle)))
        shade = float(level + rng.uniform(-0.1, 0.1))
        cv2.line(image, (int(x), int(y)), end, (shade, shade, shade), 1, cv2.LINE_AA)


def text(
    image: Image, words: str, origin: tuple[int, int], scale: float, colour: tuple[float, ...], bold: bool = False
) -> None:
    """Antialiased text in `colour` (OpenCV draws text into 8-bit images only: a mask, blended)."""
    thickness = max(1, round(scale * (2.2 if bold else 1.4)))
    mask = np.zeros(image.shape[:2], np.uint8)
    cv2.putText(mask, words, origin, BOLD if bold else FONT, scale, 255, thickness, cv2.LINE_AA)
    alpha = (mask.astype(np.float32) / 255.0)[..., None]
    image[:] = image * (1 - alpha) + np.array(colour, np.float32) * alpha


def centred(image: Image, words: str, y: int, scale: float, colour: tuple[float, ...], bold: bool = True) -> None:
    thickness = max(1, round(scale * (2.2 if bold else 1.4)))
    (width, _), _ = cv2.getTextSize(words, BOLD if bold else FONT, scale, thickness)
    text(image, words, ((image.shape[1] - width) // 2, y), scale, colour, bold)


def barcode(rng: np.random.Generator, image: Image, x: int, y: int, width: int, height: int) -> None:
    """Bars of random widths, as a printed code looks to a feature detector."""
    position = x
    while position < x + width:
        bar = int(rng.integers(1, 4))
        if rng.random() < 0.5:
            cv2.rectangle(image, (position, y), (position + bar - 1, y + height), (0.05, 0.05, 0.05), -1)
        position += bar


# --------------------------------------------------------------------------- surfaces


def concrete(name: str) -> Image:
    """A 4 m floor slab: trowelled concrete with aggregate, stains, tyre marks, hairline cracks, and
    the saw-cut joint along its edges (the joints of neighbouring slabs meet there)."""
    rng, size = rng_for(name), 1024
    level = 0.84 + 0.06 * noise(rng, size, size, (256, 64, 16, 4)) + 0.03 * noise(rng, size, size, (2,))
    image = grey(level, (1.0, 0.99, 0.96))
    speckle(rng, image, 9000, 2, 0.12)
    blotches(rng, image, 10, (20, 90), 0.25)
    blotches(rng, image, 40, (4, 14), 0.3)
    for _ in range(6):  # tyre marks: long faint arcs
        centre = (int(rng.integers(0, size)), int(rng.integers(0, size)))
        radius, start = int(rng.integers(300, 900)), float(rng.uniform(0, 360))
        shade = 0.68 + 0.1 * float(rng.random())
        cv2.ellipse(image, centre, (radius, radius), 0, start, start + 40, (shade, shade, shade), 7, cv2.LINE_AA)
    for _ in range(5):  # cracks: random walks
        heading = rng.uniform(0, 2 * np.pi)
        steps = 8 * np.array([np.cos(heading), np.sin(heading)]) + rng.normal(0, 4, (50, 2))
        path = rng.uniform(0, size, 2) + np.cumsum(steps, axis=0)
        cv2.polylines(image, [path.astype(np.int32)], False, (0.35, 0.35, 0.34), 1, cv2.LINE_AA)
    for edge in (0, size - 3):  # saw-cut joints, 3 texels (1 cm) wide, on every side
        image[edge : edge + 3, :] *= 0.35
        image[:, edge : edge + 3] *= 0.35
    return image


def column(name: str) -> Image:
    """A 0.4 × 4 m face of a concrete pillar: formwork board marks, pores, stains, chipped edges."""
    rng, height, width = rng_for(name), 1024, 128
    level = 0.86 + 0.05 * noise(rng, height, width, (128, 32, 8)) + 0.03 * noise(rng, height, width, (2,))
    image = grey(level)
    for y in range(0, height, 38):  # formwork boards, 15 cm
        image[y : y + 2] *= 0.8
    speckle(rng, image, 900, 1, 0.15)
    blotches(rng, image, 6, (6, 20), 0.2)
    image[:, :3] *= 0.7
    image[:, -3:] *= 0.7
    return image


def paint(name: str) -> Image:
    """Worn floor paint (lanes, wall base stripes, pillar bands): scuffed through to the concrete in
    patches, tyre-darkened; light so that the material's colour shows."""
    rng, height, width = rng_for(name), 32, 2048
    wear = noise(rng, height, width, (64, 16, 4))
    image = grey(0.93 + 0.04 * noise(rng, height, width, (8, 2)))
    worn = np.clip((wear - 0.9) * 3.0, 0.0, 1.0)[..., None]
    image = image * (1 - worn) + 0.42 * worn
    scratches(rng, image, 250, 24, 0.55)
    speckle(rng, image, 800, 1, 0.2)
    for edge in (0, height - 2):
        image[edge : edge + 2, :] *= 0.8
    return image.astype(np.float32)


def paint_across(name: str) -> Image:
    """Worn paint for markings that run along y (a box's top face maps the image's u to x)."""
    return np.ascontiguousarray(np.rot90(paint(name)))


def wall_panel(name: str) -> Image:
    """A 2.5 × 3 m sandwich panel: shallow vertical ribs, seams on its edges and a horizontal one,
    rows of screws, dirt rising from the floor, scuffs where trolleys hit."""
    rng, height, width = rng_for(name), 640, 512
    x = np.arange(width, dtype=np.float32)
    ribs = 0.04 * np.sin(2 * np.pi * x / 41.0)
    level = 0.9 + ribs[None, :] + 0.02 * noise(rng, height, width, (128, 32, 8))
    dirt = np.clip((np.arange(height, dtype=np.float32) / height - 0.7) / 0.3, 0, 1) ** 2
    level *= 1 - 0.25 * dirt[:, None] * (0.7 + 0.3 * noise(rng, height, width, (32, 8)))
    image = grey(level)
    blotches(rng, image, 5, (8, 40), 0.12)
    scratches(rng, image, 60, 40, 0.55)
    seam = (0.3, 0.3, 0.3)
    for y in (0, int(height * 0.55)):
        cv2.line(image, (0, y), (width, y), seam, 3)
    for xs in (1, width - 2):
        cv2.line(image, (xs, 0), (xs, height), seam, 3)
    for y in (12, int(height * 0.55) + 12, height - 12):
        for xs in range(16, width, 64):
            cv2.circle(image, (xs, y), 3, (0.45, 0.45, 0.45), -1, cv2.LINE_AA)
    return image


def upright(name: str) -> Image:
    """A rack upright's face (8 cm × 2.4 m): pairs of teardrop slots every 5 cm, chipped paint."""
    rng, height, width = rng_for(name), 1024, 48
    image = grey(0.88 + 0.04 * noise(rng, height, width, (64, 8)))
    step = round(height * 0.05 / 2.4)
    for y in range(step // 2, height, step):
        for x in (width // 3, 2 * width // 3):
            cv2.ellipse(image, (x, y), (3, 5), 0, 0, 360, (0.08, 0.08, 0.08), -1, cv2.LINE_AA)
            cv2.circle(image, (x, y - 5), 2, (0.08, 0.08, 0.08), -1, cv2.LINE_AA)
    speckle(rng, image, 120, 2, 0.25)
    scratches(rng, image, 40, 30, 0.6)
    return image


def beam(name: str) -> Image:
    """A rack beam's face (2.4 × 0.1 m): the step along its top, scratches, the load sign."""
    rng, height, width = rng_for(name), 48, 1024
    image = grey(0.9 + 0.04 * noise(rng, height, width, (128, 16, 4)))
    image[: height // 6] *= 0.72
    scratches(rng, image, 120, 30, 0.6)
    speckle(rng, image, 150, 1, 0.25)
    for x0 in (60, width - 220):
        cv2.rectangle(image, (x0, 14), (x0 + 160, 42), (1.0, 1.0, 1.0), -1)
        cv2.rectangle(image, (x0, 14), (x0 + 160, 42), (0.1, 0.1, 0.1), 1)
        text(image, "MAX 1000 kg", (x0 + 6, 34), 0.5, (0.05, 0.05, 0.05), bold=True)
    return image


def wire_deck(name: str) -> Image:
    """A rack shelf's wire deck: a grid of steel wire over dark gaps, channels underneath."""
    rng, height, width = rng_for(name), 256, 768
    image = grey(0.25 + 0.05 * noise(rng, height, width, (32, 8)))
    for x in range(0, width, 12):
        cv2.line(image, (x, 0), (x, height), (0.95, 0.95, 0.95), 2, cv2.LINE_AA)
    for y in range(0, height, 40):
        cv2.line(image, (0, y), (width, y), (0.9, 0.9, 0.9), 3, cv2.LINE_AA)
    speckle(rng, image, 200, 1, 0.3)
    return image


def pallet(name: str) -> Image:
    """A wooden pallet: planks with grain and knots, dark gaps between them, nail heads."""
    rng, size = rng_for(name), 512
    grain = noise(rng, size // 16, size, (16, 4))
    grain = np.asarray(cv2.resize(grain, (size, size), interpolation=cv2.INTER_LINEAR), np.float32)
    level = 0.85 + 0.07 * grain + 0.03 * noise(rng, size, size, (4,))
    image = grey(level)
    plank = size // 7
    for y in range(plank, size, plank):
        image[y - 6 : y + 6] *= 0.25
    for y in range(plank // 2, size, plank):
        for x in (30, size // 2, size - 30):
            cv2.circle(image, (x + int(rng.integers(-6, 7)), y), 4, (0.3, 0.3, 0.3), -1, cv2.LINE_AA)
    blotches(rng, image, 12, (6, 18), 0.35)
    return image


def carton(name: str) -> Image:
    """A load's wrapping: fibre, the tape band, a shipping label (text and barcode), a printed logo,
    handling marks; the SDF's colour tints it."""
    rng, size = rng_for(name), 512
    image = grey(0.8 + 0.03 * noise(rng, size, size, (64, 8, 2)))
    band = size // 2
    image[band - 36 : band + 36] = np.clip(image[band - 36 : band + 36] * 1.12, 0, 1)
    cv2.line(image, (0, band - 36), (size, band - 36), (0.6, 0.6, 0.6), 1)
    cv2.line(image, (0, band + 36), (size, band + 36), (0.6, 0.6, 0.6), 1)
    x0, y0 = int(rng.integers(24, 200)), int(rng.integers(300, 340))
    cv2.rectangle(image, (x0, y0), (x0 + 260, y0 + 150), (1.0, 1.0, 1.0), -1)
    cv2.rectangle(image, (x0, y0), (x0 + 260, y0 + 150), (0.2, 0.2, 0.2), 1)
    alphabet = np.array(list("ABCDEFGHJKLMNPRSTUVWXYZ0123456789"))
    for row in range(3):
        words = "".join(rng.choice(alphabet, int(rng.integers(8, 16))))
        text(image, words, (x0 + 10, y0 + 26 + 22 * row), 0.55, (0.05, 0.05, 0.05))
    barcode(rng, image, x0 + 12, y0 + 92, 236, 46)
    brand = "".join(rng.choice(alphabet[:23], 5))
    centre = (int(rng.integers(90, 420)), int(rng.integers(70, 130)))
    cv2.circle(image, centre, 46, (0.15, 0.15, 0.15), 6, cv2.LINE_AA)
    triangle = np.array([[0, -32], [28, 18], [-28, 18]]) + centre
    cv2.fillPoly(image, [triangle.astype(np.int32)], (0.15, 0.15, 0.15), cv2.LINE_AA)
    text(image, brand, (centre[0] - 60, centre[1] + 80), 1.2, (0.1, 0.1, 0.1), bold=True)
    for k in range(2):  # "this way up" arrows
        x = size - 80 + 32 * k
        cv2.arrowedLine(image, (x, 470), (x, 400), (0.1, 0.1, 0.1), 5, cv2.LINE_AA, tipLength=0.4)
    scratches(rng, image, 30, 40, 0.55)
    return image


def pegboard(name: str) -> Image:
    """The work cell's tool panel: a pegboard with holes every 25 mm and tool outlines."""
    rng, height, width = rng_for(name), 288, 512
    image = grey(0.9 + 0.03 * noise(rng, height, width, (32, 4)))
    for y in range(8, height, 8):
        for x in range(8, width, 8):
            cv2.circle(image, (x, y), 1, (0.2, 0.2, 0.2), -1, cv2.LINE_AA)
    for _ in range(9):
        x, y = int(rng.integers(30, width - 30)), int(rng.integers(30, height - 90))
        length = int(rng.integers(50, 90))
        cv2.rectangle(image, (x - 5, y), (x + 5, y + length), (0.1, 0.1, 0.1), 2, cv2.LINE_AA)
        cv2.circle(image, (x, y), 12, (0.1, 0.1, 0.1), 2, cv2.LINE_AA)
    return image


def bin_wall(name: str) -> Image:
    """A plastic bin's side: moulded ribs and a white label holder with a part number."""
    rng, height, width = rng_for(name), 160, 320
    image = grey(0.88 + 0.03 * noise(rng, height, width, (16, 4)))
    for x in range(20, width, 40):
        image[:, x : x + 5] *= 0.75
    cv2.rectangle(image, (100, 40), (220, 100), (1.0, 1.0, 1.0), -1)
    cv2.rectangle(image, (100, 40), (220, 100), (0.2, 0.2, 0.2), 2)
    part = f"P-{int(rng.integers(1000, 9999))}"
    text(image, part, (112, 80), 0.8, (0.05, 0.05, 0.05), bold=True)
    scratches(rng, image, 25, 20, 0.6)
    return image


# --------------------------------------------------------------------------- signs (their own colours)


def sign_caution(_name: str) -> Image:
    """A yellow warning triangle with its word and the reason."""
    image = np.full((512, 512, 3), (0.98, 0.82, 0.05), np.float32)
    cv2.rectangle(image, (0, 0), (511, 511), (0.05, 0.05, 0.05), 14)
    triangle = np.array([[256, 40], [450, 330], [62, 330]], np.int32)
    cv2.fillPoly(image, [triangle], (0.05, 0.05, 0.05), cv2.LINE_AA)
    inner = np.array([[256, 90], [405, 308], [107, 308]], np.int32)
    cv2.fillPoly(image, [inner], (0.98, 0.82, 0.05), cv2.LINE_AA)
    centred(image, "!", 290, 5.0, (0.05, 0.05, 0.05))
    centred(image, "CAUTION", 400, 2.2, (0.05, 0.05, 0.05))
    centred(image, "ROBOT TRAFFIC", 470, 1.4, (0.05, 0.05, 0.05))
    return image


def sign_speed(_name: str) -> Image:
    """A round speed limit: red ring, black figure."""
    image = np.full((512, 512, 3), 0.97, np.float32)
    cv2.circle(image, (256, 230), 200, (0.8, 0.05, 0.05), 44, cv2.LINE_AA)
    centred(image, "6", 300, 6.0, (0.05, 0.05, 0.05))
    centred(image, "km/h  MAX SPEED", 485, 1.3, (0.05, 0.05, 0.05))
    return image


def sign_exit(_name: str) -> Image:
    """A green emergency exit sign with a running figure's arrow."""
    image = np.full((256, 512, 3), (0.05, 0.55, 0.25), np.float32)
    cv2.rectangle(image, (10, 10), (501, 245), (0.97, 0.97, 0.97), 6)
    text(image, "EXIT", (40, 170), 3.6, (0.97, 0.97, 0.97), bold=True)
    cv2.arrowedLine(image, (330, 128), (470, 128), (0.97, 0.97, 0.97), 22, cv2.LINE_AA, tipLength=0.45)
    return image


def sign_aisle(name: str) -> Image:
    """A blue aisle sign: its number large, the bays it holds small."""
    number = name.rsplit("_", 1)[1]
    image = np.full((512, 512, 3), (0.08, 0.25, 0.6), np.float32)
    cv2.rectangle(image, (12, 12), (499, 499), (0.97, 0.97, 0.97), 8)
    centred(image, "AISLE", 110, 2.4, (0.97, 0.97, 0.97))
    centred(image, number, 380, 10.0, (0.97, 0.97, 0.97))
    centred(image, f"BAYS {number}01-{number}12", 470, 1.3, (0.97, 0.97, 0.97))
    return image


# --------------------------------------------------------------------------- what is written where

WORLD_TEXTURES: dict[str, Callable[[str], Image]] = {
    "floor_a.jpg": concrete,
    "floor_b.jpg": concrete,
    "paint.png": paint,
    "paint_v.png": paint_across,
    "wall_panel_a.jpg": wall_panel,
    "wall_panel_b.jpg": wall_panel,
    "wall_panel_c.jpg": wall_panel,
    "sign_caution.png": sign_caution,
    "sign_speed.png": sign_speed,
    "sign_exit.png": sign_exit,
    **{f"sign_aisle_{n}.png": sign_aisle for n in "1234"},
}
"""worlds/textures/: the hall's own surfaces."""
MODEL_TEXTURES: dict[str, dict[str, Callable[[str], Image]]] = {
    "rack": {
        "upright.png": upright,
        "beam.png": beam,
        "wire_deck.png": wire_deck,
        "pallet.jpg": pallet,
        "carton_a.jpg": carton,
        "carton_b.jpg": carton,
        "carton_c.jpg": carton,
    },
    "pillar": {"column.jpg": column, "paint.png": paint},
    "workcell": {"pegboard.png": pegboard, "paint.png": paint, "paint_v.png": paint_across},
    "bin": {"bin_wall.png": bin_wall},
}
"""worlds/models/<model>/materials/textures/: each model's own, beside it (Gazebo's layout)."""


def targets(out: Path | None = None) -> dict[Path, Callable[[str], Image]]:
    """Every image this script writes, by path; under `out` instead of the repository when given."""
    world_dir = out / "textures" if out else HERE
    models = out / "models" if out else MODELS
    files = {world_dir / name: make for name, make in WORLD_TEXTURES.items()}
    for model, textures in MODEL_TEXTURES.items():
        files.update({models / model / "materials" / "textures" / n: m for n, m in textures.items()})
    return files


def write(path: Path, image: Image) -> None:
    """8-bit, BGR as OpenCV writes; JPEG (quality 90) for the noisy surfaces, PNG for the rest."""
    pixels = cv2.cvtColor(np.clip(image * 255.0 + 0.5, 0, 255).astype(np.uint8), cv2.COLOR_RGB2BGR)
    params = [cv2.IMWRITE_JPEG_QUALITY, 90] if path.suffix == ".jpg" else [cv2.IMWRITE_PNG_COMPRESSION, 9]
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), pixels, params):
        raise OSError(f"{path}: OpenCV could not write the image")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="write under this folder instead of the repository's worlds/")
    args = parser.parse_args()
    for path, make in targets(args.out).items():
        write(path, make(path.stem))
        print(f"{path} {path.stat().st_size // 1024} KiB")


if __name__ == "__main__":
    main()
