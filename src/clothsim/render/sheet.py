"""Labelled contact sheets: many images in one grid, each with a caption."""

from __future__ import annotations

import math

import numpy as np


def _font(size: int):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1 has one bitmap size
        return ImageFont.load_default()


def contact_sheet(images: list[np.ndarray], labels: list[str], columns: int | None = None,
                  background: tuple[int, int, int] = (24, 26, 32)) -> np.ndarray:
    """Images (all the same size) in a grid with a caption strip under each."""
    from PIL import Image, ImageDraw

    if not images:
        raise ValueError("a contact sheet needs at least one image")
    h, w = images[0].shape[:2]
    columns = columns or (len(images) if len(images) <= 4 else math.ceil(math.sqrt(len(images))))
    rows = math.ceil(len(images) / columns)
    font_size = max(12, w // 18)
    strip = int(font_size * 1.8)
    sheet = Image.new("RGB", (columns * w, rows * (h + strip)), background)
    draw = ImageDraw.Draw(sheet)
    font = _font(font_size)
    for k, (img, label) in enumerate(zip(images, labels)):
        x, y = (k % columns) * w, (k // columns) * (h + strip)
        sheet.paste(Image.fromarray(img), (x, y))
        tw = draw.textlength(label, font=font)
        draw.text((x + (w - tw) / 2, y + h + (strip - font_size) / 2 - 1), label, fill=(235, 235, 235), font=font)
    return np.asarray(sheet)
