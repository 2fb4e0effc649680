"""Log-log line plots as PNG files, drawn with numpy alone: the add-on ships no plotting library.

Shapes are rasterised from distance fields (a pixel's coverage is how far inside the stroke its centre lies), so
lines and markers are antialiased. Text uses a built-in 5 × 7 bitmap font of capitals, digits and a little
punctuation; lowercase is drawn as capitals. Images are (H, W, 4) uint8 sRGB, row 0 at the top, and are written
as PNG with zlib from the standard library.
"""

from dataclasses import dataclass
import math
import struct
import zlib

import numpy as np

# 5 × 7 glyphs: seven rows, each a 5-bit number in hex, the top row first and bit 4 the leftmost column.
FONT = {
    "0": "0E11131519110E", "1": "040C040404040E", "2": "0E11010204081F",
    "3": "1F02040201110E", "4": "02060A121F0202", "5": "1F101E0101110E", "6": "0608101E11110E",
    "7": "1F010204080808", "8": "0E11110E11110E", "9": "0E11110F01020C",
    "A": "0E1111111F1111", "B": "1E11111E11111E", "C": "0E11101010110E", "D": "1C12111111121C",
    "E": "1F10101E10101F", "F": "1F10101E101010", "G": "0E11101711110F",
    "H": "1111111F111111", "I": "0E04040404040E", "J": "0702020202120C", "K": "11121418141211",
    "L": "1010101010101F", "M": "111B1515111111", "N": "11111915131111", "O": "0E11111111110E",
    "P": "1E11111E101010", "Q": "0E11111115120D", "R": "1E11111E141211", "S": "0F10100E01011E",
    "T": "1F040404040404", "U": "1111111111110E", "V": "11111111110A04",
    "W": "1111111515150A", "X": "11110A040A1111", "Y": "1111110A040404", "Z": "1F01020408101F",
    " ": "00000000000000", ".": "00000000000C0C", ",": "000000000C0408", "-": "0000001F000000",
    "(": "02040808080402", ")": "08040202020408", "%": "18190204081303", "/": "00010204081000",
    ":": "000C0C000C0C00", "=": "00001F001F0000", "+": "0004041F040400", "×": "00110A040A1100",
    "_": "0000000000001F", "'": "0C040800000000",
}
GLYPH_WIDTH, GLYPH_HEIGHT, GLYPH_SPACING = 5, 7, 1

BACKGROUND = (255, 255, 255)
INK = (40, 40, 40)
GRID = (232, 232, 232)
GRID_MAJOR = (190, 190, 190)
# Colours told apart also by readers with red-green colour blindness (Okabe-Ito blue and vermilion).
BLUE = (0, 114, 178)
VERMILION = (213, 94, 0)


@dataclass
class Series:
    label: str
    x: list
    y: list
    colour: tuple  # sRGB, 0-255
    marker: str = "circle"  # or "square", or "ring": hollow, so a curve drawn over another leaves it visible
    point_labels: tuple = ()  # text beside each point, e.g. its sample count
    width: float = 2.0  # of the line, in pixels


def glyph_mask(character: str) -> np.ndarray:
    """(7, 5) bool; characters the font lacks are drawn as spaces, so a label never fails."""
    rows = bytes.fromhex(FONT.get(character.upper(), FONT[" "]))
    return np.array([[row >> (GLYPH_WIDTH - 1 - column) & 1 for column in range(GLYPH_WIDTH)] for row in rows],
                    dtype=bool)


def text_mask(text: str, scale: int = 2) -> np.ndarray:
    """The text as one bool mask, `scale` pixels per font pixel."""
    if not text:
        return np.zeros((GLYPH_HEIGHT * scale, 0), dtype=bool)
    columns = []
    for character in text:
        columns += [glyph_mask(character), np.zeros((GLYPH_HEIGHT, GLYPH_SPACING), dtype=bool)]
    return np.kron(np.hstack(columns[:-1]), np.ones((scale, scale), dtype=bool))


class Canvas:
    """An sRGB float image to draw on; coordinates are pixels, x to the right, y down, (0, 0) the top left corner."""

    def __init__(self, width: int, height: int, background=BACKGROUND):
        self.pixels = np.empty((height, width, 3))
        self.pixels[:] = np.asarray(background) / 255.0

    @property
    def width(self) -> int:
        return self.pixels.shape[1]

    @property
    def height(self) -> int:
        return self.pixels.shape[0]

    def rgba(self) -> np.ndarray:
        rgb = np.round(np.clip(self.pixels, 0.0, 1.0) * 255).astype(np.uint8)
        return np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 255, dtype=np.uint8)], axis=2)

    def _blend(self, top, left, coverage, colour):
        """Paints `colour` with per-pixel coverage (h, w) ∈ [0, 1] at (top, left), clipped to the canvas."""
        h, w = coverage.shape
        y0, x0 = max(top, 0), max(left, 0)
        y1, x1 = min(top + h, self.height), min(left + w, self.width)
        if y0 >= y1 or x0 >= x1:
            return
        alpha = coverage[y0 - top:y1 - top, x0 - left:x1 - left, None]
        region = self.pixels[y0:y1, x0:x1]
        region[:] = region * (1.0 - alpha) + alpha * (np.asarray(colour) / 255.0)

    def _field(self, x_min, y_min, x_max, y_max):
        """Pixel-centre coordinates over a box: (top, left, xs, ys)."""
        left, top = math.floor(x_min), math.floor(y_min)
        ys, xs = np.mgrid[top:math.ceil(y_max) + 1, left:math.ceil(x_max) + 1] + 0.5
        return top, left, xs, ys

    def line(self, start, end, colour, width=1.0):
        """A straight stroke from start to end (x, y), `width` pixels wide."""
        (ax, ay), (bx, by) = start, end
        reach = width / 2 + 1
        top, left, xs, ys = self._field(min(ax, bx) - reach, min(ay, by) - reach,
                                        max(ax, bx) + reach, max(ay, by) + reach)
        dx, dy = bx - ax, by - ay
        along = np.clip(((xs - ax) * dx + (ys - ay) * dy) / max(dx * dx + dy * dy, 1e-12), 0.0, 1.0)
        distance = np.hypot(xs - ax - along * dx, ys - ay - along * dy)
        self._blend(top, left, np.clip(width / 2 + 0.5 - distance, 0.0, 1.0), colour)

    def polyline(self, points, colour, width=1.0):
        for start, end in zip(points[:-1], points[1:]):
            self.line(start, end, colour, width)

    def marker(self, centre, colour, shape="circle", radius=4.0):
        x, y = centre
        reach = radius + 2
        top, left, xs, ys = self._field(x - reach, y - reach, x + reach, y + reach)
        if shape == "circle":
            coverage = radius + 0.5 - np.hypot(xs - x, ys - y)
        elif shape == "square":
            coverage = radius + 0.5 - np.maximum(np.abs(xs - x), np.abs(ys - y))
        elif shape == "ring":
            coverage = 1.25 - np.abs(np.hypot(xs - x, ys - y) - (radius + 1.5))  # 1.5 pixels wide, outside radius
        else:
            raise ValueError(f"unknown marker {shape!r}: expected 'circle', 'square' or 'ring'")
        self._blend(top, left, np.clip(coverage, 0.0, 1.0), colour)

    def rectangle(self, left, top, right, bottom, colour):
        """A filled axis-aligned rectangle (integer pixel bounds, right and bottom excluded)."""
        self._blend(top, left, np.ones((bottom - top, right - left)), colour)

    def text(self, position, text, colour=INK, scale=2, align="left", vertical=False):
        """Text with its top edge at y and its left end, centre or right end at x (`align`); `vertical` turns it
        a quarter to read upwards, centred on `position`."""
        mask = text_mask(text, scale)
        x, y = (int(round(value)) for value in position)
        if vertical:
            mask = np.rot90(mask)
            top, left = y - mask.shape[0] // 2, x - mask.shape[1] // 2
        else:
            top, left = y, x - {"left": 0, "centre": mask.shape[1] // 2, "right": mask.shape[1]}[align]
        self._blend(top, left, mask.astype(float), colour)


def text_width(text: str, scale: int = 2) -> int:
    return text_mask(text, scale).shape[1]


class LogAxes:
    """Maps data to pixels on log-log axes that span the data with a margin."""

    def __init__(self, box, x_values, y_values):
        self.left, self.top, self.right, self.bottom = box
        self.x_range = _log_range(x_values)
        self.y_range = _log_range(y_values)

    def to_pixel(self, x, y):
        (x0, x1), (y0, y1) = self.x_range, self.y_range
        u = (math.log10(x) - x0) / (x1 - x0)
        v = (math.log10(y) - y0) / (y1 - y0)
        return self.left + u * (self.right - self.left), self.bottom - v * (self.bottom - self.top)

    def ticks(self, log_range):
        """(value, labelled) of the grid lines: 1-9 × each decade in range; decades are labelled, and 2 and 5 too
        when the axis spans less than 2.5 decades."""
        low, high = log_range
        values = [m * 10.0 ** e for e in range(math.floor(low), math.ceil(high)) for m in range(1, 10)]
        inside = [v for v in values if low <= math.log10(v) <= high]
        labelled = {1} if high - low >= 2.5 else {1, 2, 5}
        return [(v, _mantissa(v) in labelled) for v in inside]


def _mantissa(value) -> int:
    return round(value / 10.0 ** math.floor(math.log10(value) + 1e-9))


def _log_range(values):
    """(low, high) in log10 around the positive values, with a margin so no point sits on the frame."""
    logs = [math.log10(v) for v in values if v > 0 and math.isfinite(v)]
    if not logs:
        return 0.0, 1.0
    low, high = min(logs), max(logs)
    margin = max(0.08 * (high - low), 0.15)
    return low - margin, high + margin


def tick_label(value) -> str:
    """Plain digits from 0.001 to 10000 (0.002, 0.5, 20), else 2E-5 or 5E6."""
    exponent = math.floor(math.log10(value) + 1e-9)
    if -3 <= exponent <= 4:
        return f"{value:.{max(0, -exponent)}f}"
    return f"{_mantissa(value)}E{exponent}"


def log_log_plot(series, title, x_label, y_label, size=(760, 500)) -> np.ndarray:
    """A log-log plot of the series (points joined by lines) with a grid, axis labels and a legend:
    (H, W, 4) uint8 sRGB. Points at or below zero have no place on log axes and are left out."""
    width, height = size
    canvas = Canvas(width, height)
    box = (100, 52, width - 24, height - 70)  # left, top, right, bottom of the plotting area
    kept = [[(x, y) for x, y in zip(s.x, s.y) if x > 0 and y > 0] for s in series]
    axes = LogAxes(box, [x for points in kept for x, _ in points], [y for points in kept for _, y in points])
    _draw_grid(canvas, axes)
    canvas.text((width // 2, 14), title, align="centre")
    canvas.text(((box[0] + box[2]) // 2, height - 26), x_label, align="centre")
    canvas.text((16, (box[1] + box[3]) // 2), y_label, vertical=True)
    pixels = [[axes.to_pixel(x, y) for x, y in points] for points in kept]
    for s, points in zip(series, pixels):
        canvas.polyline(points, s.colour, width=s.width)
        for (px, py), label in zip(points, s.point_labels or [""] * len(points)):
            canvas.marker((px, py), s.colour, s.marker)
            canvas.text((px + 6, py + 6), label, colour=s.colour, scale=1)
    _draw_legend(canvas, box, series, [p for points in pixels for p in points])
    return canvas.rgba()


def _draw_grid(canvas, axes):
    left, top, right, bottom = axes.left, axes.top, axes.right, axes.bottom
    y_low, x_low = 10.0 ** axes.y_range[0], 10.0 ** axes.x_range[0]
    for value, labelled in axes.ticks(axes.x_range):
        x, _ = axes.to_pixel(value, y_low)
        canvas.line((x, top), (x, bottom), GRID_MAJOR if labelled else GRID)
        if labelled:
            canvas.line((x, bottom), (x, bottom + 6), INK)
            canvas.text((x, bottom + 10), tick_label(value), align="centre")
    for value, labelled in axes.ticks(axes.y_range):
        _, y = axes.to_pixel(x_low, value)
        canvas.line((left, y), (right, y), GRID_MAJOR if labelled else GRID)
        if labelled:
            canvas.line((left - 6, y), (left, y), INK)
            canvas.text((left - 10, y - 7), tick_label(value), align="right")
    canvas.polyline([(left, top), (right, top), (right, bottom), (left, bottom), (left, top)], INK)


def _draw_legend(canvas, box, series, points):
    """A framed list of the series (line, marker, label) in whichever corner of the plotting area holds the
    fewest points: error-against-time curves fall from top left to bottom right."""
    row_height, inset = 24, 10
    width = max(text_width(s.label) for s in series) + 62
    height = row_height * len(series) + 8
    left_corner, right_corner = box[0] + inset, box[2] - inset - width
    top_corner, bottom_corner = box[1] + inset, box[3] - inset - height
    corners = [(right_corner, top_corner), (left_corner, bottom_corner),
               (right_corner, bottom_corner), (left_corner, top_corner)]

    def covered(corner):
        x, y = corner
        return sum(x - 8 <= px <= x + width + 8 and y - 8 <= py <= y + height + 8 for px, py in points)

    left, top = min(corners, key=covered)
    right, bottom = left + width, top + height
    canvas.rectangle(left, top, right, bottom, BACKGROUND)
    canvas.polyline([(left, top), (right, top), (right, bottom), (left, bottom), (left, top)], INK)
    for row, s in enumerate(series):
        y = top + 16 + row * row_height
        canvas.line((left + 10, y), (left + 42, y), s.colour, width=s.width)
        canvas.marker((left + 26, y), s.colour, s.marker)
        canvas.text((left + 52, y - 7), s.label)


def png_bytes(rgba: np.ndarray) -> bytes:
    """An (H, W, 4) uint8 image, row 0 at the top, as PNG (8-bit RGBA, no filtering)."""
    height, width = rgba.shape[:2]
    rows = np.hstack([np.zeros((height, 1), dtype=np.uint8), np.ascontiguousarray(rgba, dtype=np.uint8)
                      .reshape(height, width * 4)])

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)  # 8 bits, RGBA, deflate, no filter, no interlace
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows.tobytes(), 9))
            + chunk(b"IEND", b""))


def write_png(path: str, rgba: np.ndarray):
    with open(path, "wb") as handle:
        handle.write(png_bytes(rgba))
