"""The numpy plot: PNG encoding, the bitmap font, where points land on log-log axes, and the legend's corner."""

import math
import struct
import zlib

import numpy as np

from prt_addon import plot


def decode_png(data: bytes) -> np.ndarray:
    """Reads back what png_bytes writes (8-bit RGBA, filter 0 on every row), checking the chunks' CRCs."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    position, chunks = 8, {}
    while position < len(data):
        (length,) = struct.unpack(">I", data[position:position + 4])
        kind, body = data[position + 4:position + 8], data[position + 8:position + 8 + length]
        (crc,) = struct.unpack(">I", data[position + 8 + length:position + 12 + length])
        assert crc == zlib.crc32(kind + body)
        chunks[kind] = body
        position += 12 + length
    width, height, depth, colour_type = struct.unpack(">IIBB", chunks[b"IHDR"][:10])
    assert (depth, colour_type) == (8, 6) and b"IEND" in chunks
    rows = np.frombuffer(zlib.decompress(chunks[b"IDAT"]), dtype=np.uint8).reshape(height, 1 + 4 * width)
    assert not rows[:, 0].any()
    return rows[:, 1:].reshape(height, width, 4)


def test_png_round_trip():
    rgba = np.random.default_rng(1).integers(0, 256, size=(7, 11, 4), dtype=np.uint8)
    np.testing.assert_array_equal(decode_png(plot.png_bytes(rgba)), rgba)


def test_every_glyph_is_five_by_seven_and_text_is_spaced():
    for character, rows in plot.FONT.items():
        values = bytes.fromhex(rows)
        assert len(values) == 7 and max(values) < 32, character
    assert plot.glyph_mask("a").tolist() == plot.glyph_mask("A").tolist()  # lowercase is drawn as capitals
    assert plot.glyph_mask("1")[:, 2].all()  # the stem of a one
    mask = plot.text_mask("E1", scale=2)
    assert mask.shape == (14, 2 * (5 + 1 + 5))
    assert mask[:, :10].any(axis=0).all() and not mask[:, 10:12].any()  # one blank column between glyphs


def colour_at(image, x, y, colour, reach=2):
    """Whether a pixel within `reach` of (x, y) has exactly this colour."""
    window = image[int(y) - reach:int(y) + reach + 1, int(x) - reach:int(x) + reach + 1, :3]
    return bool((window == np.array(colour, dtype=np.uint8)).all(axis=-1).any())


def test_points_land_where_log_log_axes_put_them():
    xs, ys = [0.1, 1.0, 10.0], [0.5, 0.05, 0.005]
    image = plot.log_log_plot([plot.Series("estimate", xs, ys, plot.BLUE)], "T", "x", "y", size=(400, 300))
    assert image.shape == (300, 400, 4) and image.dtype == np.uint8
    axes = plot.LogAxes((100, 52, 400 - 24, 300 - 70), xs, ys)
    pixels = [axes.to_pixel(x, y) for x, y in zip(xs, ys)]
    for x, y in pixels:
        assert colour_at(image, x, y, plot.BLUE)
    # equal ratios are equal distances, and a falling curve goes down the image
    assert math.isclose(pixels[1][0] - pixels[0][0], pixels[2][0] - pixels[1][0], rel_tol=1e-9)
    assert pixels[0][1] < pixels[1][1] < pixels[2][1]
    assert not colour_at(image, (pixels[0][0] + pixels[2][0]) / 2, pixels[0][1], plot.BLUE, reach=4)


def test_ticks_label_decades_or_more_when_the_range_is_short():
    wide = plot.LogAxes((0, 0, 100, 100), [1e-3, 1e2], [1, 10])
    labelled = [value for value, shown in wide.ticks(wide.x_range) if shown]
    assert labelled == [1e-3, 1e-2, 1e-1, 1.0, 10.0, 100.0]
    short = plot.LogAxes((0, 0, 100, 100), [0.03, 0.2], [1, 10])
    assert [plot.tick_label(v) for v, shown in short.ticks(short.x_range) if shown] == ["0.05", "0.1", "0.2"]
    assert [plot.tick_label(v) for v in (2e-5, 0.002, 0.5, 20.0, 5e6)] == ["2E-5", "0.002", "0.5", "20", "5E6"]


def test_legend_goes_to_the_corner_without_points():
    """Error against time falls from top left to bottom right: the legend must not cover the curve."""
    falling = plot.Series("falling", [1, 10, 100], [1.0, 0.1, 0.01], plot.VERMILION)
    rising = plot.Series("rising", [1, 10, 100], [0.01, 0.1, 1.0], plot.VERMILION)
    size = (500, 400)
    box = (100, 52, size[0] - 24, size[1] - 70)
    top_right = (box[2] - 20, box[1] + 20)
    bottom_right = (box[2] - 20, box[3] - 20)
    # the legend's frame is ink-coloured: look for it near each corner
    falling_image = plot.log_log_plot([falling], "", "", "", size)
    rising_image = plot.log_log_plot([rising], "", "", "", size)
    assert colour_at(falling_image, *top_right, plot.INK, reach=12)
    assert not colour_at(falling_image, *bottom_right, plot.INK, reach=12)
    assert colour_at(rising_image, *bottom_right, plot.INK, reach=12)  # top right and bottom left are taken
    assert not colour_at(rising_image, *top_right, plot.INK, reach=12)
