"""Pillow overlays: colour bars and label bands under the rendered panels."""

from __future__ import annotations

import os

import numpy as np

from .backend import colormap, pil_modules

_FONT_PATH: list = []


def load_font(size: int):
    """DejaVu Sans from matplotlib's data (it has Greek: λ), else Pillow's default font."""
    _, _, ImageFont = pil_modules()
    if not _FONT_PATH:
        path = None
        try:
            import matplotlib

            cand = os.path.join(matplotlib.get_data_path(), "fonts", "ttf", "DejaVuSans.ttf")
            path = cand if os.path.exists(cand) else None
        except Exception:   # noqa: BLE001 - no matplotlib, or a broken one: Pillow's own font
            pass
        _FONT_PATH.append(path)
    if _FONT_PATH[0]:
        try:
            return ImageFont.truetype(_FONT_PATH[0], size)
        except OSError:
            pass
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1: fixed bitmap font
        return ImageFont.load_default()


def format_tick(x: float) -> str:
    if x == 0:
        return "0"
    return f"{x:.3g}".replace("e-0", "e-").replace("e+0", "e")


def colorbar_font_size(width: int) -> int:
    return int(np.clip(round(0.016 * width), 11, 16))


def colorbar_height(width: int) -> int:
    """Height of the colour-bar band: title line, bar, tick labels."""
    font_px = colorbar_font_size(width)
    return int(round(font_px * 1.5 + max(8, 0.9 * font_px) + font_px * 1.6 + 6))


def tick_labels(clim, diverging: bool, data_range=None) -> list[tuple[float, str]]:
    """The colour bar's ticks: (value, text).  An end the data pass is marked ``≤ lo`` / ``≥ hi``:
    the colours there stand for every value beyond it (the range is clipped)."""
    lo, hi = float(clim[0]), float(clim[1])
    ticks = [(lo, format_tick(lo)), (hi, format_tick(hi))]
    if diverging and lo < 0 < hi:
        ticks.insert(1, (0.0, "0"))
    if data_range is not None:
        if data_range[0] < lo:
            ticks[0] = (lo, f"≤ {format_tick(lo)}")
        if data_range[1] > hi:
            ticks[-1] = (hi, f"≥ {format_tick(hi)}")
    return ticks


def colorbar_image(width: int, height: int, cmap_name: str, clim, label: str, diverging: bool,
                   transparent: bool, data_range=None) -> np.ndarray:
    """A horizontal colour bar: the title above it, tick values under it.  Where the data pass an end
    of the range (``data_range``), that end gets a triangle in its colour and a ``≤``/``≥`` label."""
    Image, ImageDraw, _ = pil_modules()
    mode = "RGBA" if transparent else "RGB"
    bg = (255, 255, 255, 0) if transparent else (255, 255, 255)
    im = Image.new(mode, (width, height), bg)
    draw = ImageDraw.Draw(im)
    font_px = colorbar_font_size(width)
    font = load_font(font_px)
    ink = (40, 40, 40, 255) if transparent else (40, 40, 40)
    bar_w = int(min(0.5 * width, 40 * font_px))
    bar_h = int(max(8, 0.9 * font_px))
    x0 = (width - bar_w) // 2
    y0 = int(round(font_px * 1.5))
    if label:
        tw = draw.textlength(label, font=font)
        draw.text(((width - tw) / 2, y0 - font_px * 1.35), label, fill=ink, font=font)
    grad = colormap(cmap_name)(np.linspace(0, 1, bar_w))[:, :3]
    grad = (np.round(grad * 255)).astype(np.uint8)
    strip = np.repeat(grad[None], bar_h, axis=0)
    if transparent:
        strip = np.concatenate([strip, np.full(strip.shape[:2] + (1,), 255, np.uint8)], axis=2)
    im.paste(Image.fromarray(strip, mode), (x0, y0))
    draw.rectangle([x0 - 1, y0 - 1, x0 + bar_w, y0 + bar_h], outline=ink)
    ticks = tick_labels(clim, diverging, data_range)
    for end, (x_base, x_tip) in ((0, (x0 - 2, x0 - 2 - bar_h)), (1, (x0 + bar_w + 1, x0 + bar_w + 1 + bar_h))):
        if ticks[-end][1][:1] in "≤≥":          # clipped: a triangle beyond the bar in the end's colour
            colour = tuple(int(c) for c in grad[-end]) + ((255,) if transparent else ())
            draw.polygon([(x_base, y0), (x_tip, y0 + bar_h / 2), (x_base, y0 + bar_h)], fill=colour, outline=ink)
    for t, txt in ticks:
        fx = (t - clim[0]) / (clim[1] - clim[0])
        xp = x0 + int(round(fx * (bar_w - 1)))
        draw.line([xp, y0 + bar_h, xp, y0 + bar_h + 3], fill=ink)
        tw = draw.textlength(txt, font=font)
        draw.text((min(max(xp - tw / 2, 0), width - tw), y0 + bar_h + 4), txt, fill=ink, font=font)
    return np.asarray(im)


def label_band(width: int, height: int, text: str, transparent: bool) -> np.ndarray:
    Image, ImageDraw, _ = pil_modules()
    mode = "RGBA" if transparent else "RGB"
    im = Image.new(mode, (width, height), (255, 255, 255, 0) if transparent else (255, 255, 255))
    draw = ImageDraw.Draw(im)
    font_px = max(10, int(height * 0.66))
    font = load_font(font_px)
    while font_px > 8 and draw.textlength(text, font=font) > width - 4:
        font_px -= 1
        font = load_font(font_px)
    tw = draw.textlength(text, font=font)
    draw.text(((width - tw) / 2, (height - font_px) / 2 - 1), text,
              fill=(30, 30, 30, 255) if transparent else (30, 30, 30), font=font)
    return np.asarray(im)
