"""Furniture families: storage (cabinet, dresser, bookshelf, crate), tables (table, desk,
workbench) and seating (stool, chair, armchair, wheelchair).

Storage units share a carcass (sides, back, bottom, base) and differ by their front (doors with
handles, drawers, open shelves) or their top (the crate is open): from behind they are the same
box. Tables share a top on four legs and differ by what hangs under the top (a drawer pedestal
on the +y end facing +x, a low shelf), hidden from above. Seats share a seat on four legs and
differ by a back (at -x), arms and wheels.
"""

from __future__ import annotations

import numpy as np

from rapomdp.data.procedural.body import Body, Parts
from rapomdp.data.procedural.parts import ellipsoid, slab, spoked_wheel, tube

Y = (0.0, 1.0, 0.0)


def _legs(corners: np.ndarray, top: float, radius: float, square: bool) -> Parts:
    if square:
        return [slab((x - radius, y - radius, 0.0), (x + radius, y + radius, top))
                for x, y in corners]
    return [tube((x, y, 0.0), (x, y, top), radius) for x, y in corners]


def _corners(half_x: float, half_y: float) -> np.ndarray:
    return np.array([[sx * half_x, sy * half_y] for sx in (-1, 1) for sy in (-1, 1)])


def _slab_on_legs(rng: np.random.Generator, name: str, top_z: float, depth: float, width: float,
                  thick: float, inset: float, leg: float) -> dict[str, Parts]:
    """A slab (a table top, a seat) whose top is at ``top_z`` on four round or square legs."""
    hx, hy = depth / 2, width / 2
    corners = _corners(hx - inset, hy - inset)
    return {name: [slab((-hx, -hy, top_z - thick), (hx, hy, top_z))],
            "legs": _legs(corners, top_z - thick, leg, bool(rng.random() < 0.5))}


def _knob(rng: np.random.Generator, centre: np.ndarray, size: float, bar: bool,
          along: str = "y") -> Parts:
    """A knob (a small sphere) or a bar pull standing off a front face at +x."""
    if not bar:
        return [ellipsoid((size * 0.6, size * 0.5, size * 0.5), centre + [size * 0.5, 0, 0], 1)]
    half = np.array([0, size * 2.0, 0]) if along == "y" else np.array([0, 0, size * 2.0])
    stand = centre + [size * 0.9, 0, 0]
    return [tube(stand - half, stand + half, size * 0.25, 6),
            tube(centre - half * 0.9, stand - half * 0.9, size * 0.2, 6),
            tube(centre + half * 0.9, stand + half * 0.9, size * 0.2, 6)]


# --- storage -----------------------------------------------------------------------------------

def storage_body(rng: np.random.Generator) -> Body:
    height = rng.uniform(0.6, 1.6)
    width = rng.uniform(0.5, 1.1)
    depth = rng.uniform(0.32, 0.5)
    t = rng.uniform(0.015, 0.03)
    base_kind = rng.integers(3)
    base_h = 0.0 if base_kind == 0 else rng.uniform(0.04, 0.12)
    hx, hy = depth / 2, width / 2
    top = base_h + height
    parts: dict[str, Parts] = {
        "sides": [slab((-hx, -hy, base_h), (hx, -hy + t, top)),
                  slab((-hx, hy - t, base_h), (hx, hy, top))],
        "back": [slab((-hx, -hy, base_h), (-hx + t, hy, top))],
        "bottom": [slab((-hx, -hy, base_h), (hx, hy, base_h + t))],
    }
    if base_kind == 1:
        parts["base"] = [slab((-hx + 0.02, -hy + 0.02, 0.0), (hx - 0.02, hy - 0.02, base_h))]
    elif base_kind == 2:
        r = rng.uniform(0.015, 0.03)
        parts["base"] = _legs(_corners(hx - r - 0.01, hy - r - 0.01), base_h + 0.005, r,
                              bool(rng.random() < 0.5))
    return Body(parts, {"height": height, "width": width, "depth": depth, "t": t,
                        "base_h": base_h, "top": top})


def _storage_top(body: Body, rng: np.random.Generator) -> Parts:
    d = body.dims
    over = rng.uniform(0.0, 0.03) if rng.random() < 0.5 else 0.0
    hx, hy = d["depth"] / 2 + over, d["width"] / 2 + over
    return [slab((-d["depth"] / 2, -hy, d["top"] - d["t"]), (hx, hy, d["top"] + over * 0.5))]


def cabinet(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    hx, hy, t = d["depth"] / 2, d["width"] / 2, d["t"]
    doors = 1 if d["width"] < 0.65 or rng.random() < 0.3 else 2
    gap = rng.uniform(0.004, 0.01)
    edges = np.linspace(-hy, hy, doors + 1)
    z0, z1 = d["base_h"] + t, d["top"] - t
    fronts: Parts = []
    bar = bool(rng.random() < 0.6)
    size = rng.uniform(0.015, 0.03)
    for i in range(doors):
        fronts.append(slab((hx - t, edges[i] + gap / 2, z0), (hx + 0.005, edges[i + 1] - gap / 2,
                                                              z1)))
        if rng.random() < 0.5:  # a raised panel on the door
            inset = min(0.08, (edges[i + 1] - edges[i]) * 0.15)
            fronts.append(slab((hx, edges[i] + inset, z0 + inset),
                               (hx + 0.012, edges[i + 1] - inset, z1 - inset)))
        handle_y = edges[i + 1] - 0.05 if i == 0 else edges[i] + 0.05
        fronts += _knob(rng, np.array([hx + 0.005, handle_y, z0 + (z1 - z0) * 0.6]), size, bar,
                        "z")
    return {"top": _storage_top(body, rng), "doors": fronts}


def dresser(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    hx, hy, t = d["depth"] / 2, d["width"] / 2, d["t"]
    rows = int(rng.integers(3, 7))
    columns = 2 if d["width"] > 0.8 and rng.random() < 0.5 else 1
    gap = rng.uniform(0.008, 0.016)
    zs = np.linspace(d["base_h"] + t, d["top"] - t, rows + 1)
    ys = np.linspace(-hy + t, hy - t, columns + 1)
    bar = bool(rng.random() < 0.5)
    size = rng.uniform(0.012, 0.025)
    drawers: Parts = [slab((hx - 0.02, -hy + t, d["base_h"] + t), (hx - 0.01, hy - t,
                                                                  d["top"] - t))]
    for r in range(rows):
        for c in range(columns):
            drawers.append(slab((hx - 0.012, ys[c] + gap / 2, zs[r] + gap / 2),
                                (hx + 0.012, ys[c + 1] - gap / 2, zs[r + 1] - gap / 2)))
            centre = np.array([hx + 0.012, (ys[c] + ys[c + 1]) / 2, (zs[r] + zs[r + 1]) / 2])
            drawers += _knob(rng, centre, size, bar)
    return {"top": _storage_top(body, rng), "drawers": drawers}


def bookshelf(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    hx, hy, t = d["depth"] / 2, d["width"] / 2, d["t"]
    shelves = int(rng.integers(2, 6))
    zs = np.linspace(d["base_h"] + t, d["top"] - t, shelves + 1)[1:-1]
    parts: Parts = [slab((-hx + t, -hy + t, z), (hx - 0.01, hy - t, z + t)) for z in zs]
    levels = np.concatenate([[d["base_h"] + t], zs + t])
    books: Parts = []
    if rng.random() < 0.6:
        room = np.diff(np.concatenate([levels, [d["top"] - t]]))
        for z, space in zip(levels, room, strict=True):
            if rng.random() < 0.4:
                continue
            y = -hy + t + rng.uniform(0.0, 0.1)
            while y < hy - t - 0.05:
                w = rng.uniform(0.02, 0.05)
                h = min(space * rng.uniform(0.6, 0.9), 0.35)
                books.append(slab((-hx + t, y, z), (-hx + t + d["depth"] * rng.uniform(0.5, 0.85),
                                                    y + w, z + h)))
                y += w + (rng.uniform(0.05, 0.25) if rng.random() < 0.15 else 0.002)
    return {"top": _storage_top(body, rng), "shelves": parts + books}


def crate(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    hx, hy, t = d["depth"] / 2, d["width"] / 2, d["t"]
    parts = {"front": [slab((hx - t, -hy, d["base_h"]), (hx, hy, d["top"]))]}
    if rng.random() < 0.5:  # carrying bars on the sides
        z = d["top"] - rng.uniform(0.06, 0.12)
        parts["handles"] = [tube((-hx * 0.4, s * (hy + 0.025), z), (hx * 0.4, s * (hy + 0.025), z),
                                 0.012, 6) for s in (-1, 1)]
    parts["rim"] = [slab((-hx, -hy, d["top"] - 0.01), (hx, -hy + t * 1.6, d["top"])),
                    slab((-hx, hy - t * 1.6, d["top"] - 0.01), (hx, hy, d["top"]))]
    return parts


# --- tables ------------------------------------------------------------------------------------

def table_body(rng: np.random.Generator) -> Body:
    height = rng.uniform(0.68, 0.78)
    depth = rng.uniform(0.55, 0.85)  # along x
    length = rng.uniform(0.9, 1.6)  # along y
    thick = rng.uniform(0.025, 0.05)
    inset = rng.uniform(0.03, 0.08)
    leg = rng.uniform(0.018, 0.035)
    hx, hy = depth / 2, length / 2
    parts = _slab_on_legs(rng, "top", height, depth, length, thick, inset, leg)
    if rng.random() < 0.5:
        a = rng.uniform(0.05, 0.09)
        ix, iy = hx - inset, hy - inset
        z0, z1 = height - thick - a, height - thick
        parts["apron"] = [slab((-ix, -iy, z0), (ix, -iy + 0.02, z1)),
                          slab((-ix, iy - 0.02, z0), (ix, iy, z1)),
                          slab((-ix, -iy, z0), (-ix + 0.02, iy, z1)),
                          slab((ix - 0.02, -iy, z0), (ix, iy, z1))]
    return Body(parts, {"height": height - thick, "depth": depth, "length": length,
                        "inset": inset, "leg": leg})


def table(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    if rng.random() > 0.35:
        return {}
    ix, iy = d["depth"] / 2 - d["inset"], d["length"] / 2 - d["inset"]
    z = rng.uniform(0.08, 0.2)
    r = d["leg"] * 0.5
    return {"stretchers": [tube((-ix, -iy, z), (-ix, iy, z), r), tube((ix, -iy, z), (ix, iy, z), r),
                           tube((-ix, 0, z), (ix, 0, z), r)]}


def desk(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    ix, iy = d["depth"] / 2 - d["inset"], d["length"] / 2 - d["inset"]
    width = rng.uniform(0.32, 0.45)
    y0 = iy - width - d["leg"]
    y1 = iy - d["leg"]
    bottom = rng.uniform(0.0, 0.06) if rng.random() < 0.6 else d["height"] * rng.uniform(0.6, 0.75)
    drawers = int(rng.integers(1, 4)) if bottom > 0.2 else int(rng.integers(2, 5))
    front = ix + rng.uniform(-0.01, 0.03)
    carcass = [slab((-ix, y0, bottom), (front - 0.015, y1, d["height"]))]
    zs = np.linspace(bottom, d["height"] - 0.01, drawers + 1)
    bar = bool(rng.random() < 0.5)
    fronts: Parts = []
    for z0, z1 in zip(zs[:-1], zs[1:], strict=True):
        fronts.append(slab((front - 0.02, y0 + 0.008, z0 + 0.006), (front, y1 - 0.008, z1 - 0.006)))
        fronts += _knob(rng, np.array([front, (y0 + y1) / 2, (z0 + z1) / 2]), 0.018, bar)
    return {"pedestal": carcass, "drawers": fronts}


def workbench(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    ix, iy = d["depth"] / 2 - d["inset"] + d["leg"], d["length"] / 2 - d["inset"] + d["leg"]
    z = rng.uniform(0.08, 0.3)
    parts = [slab((-ix, -iy, z), (ix, iy, z + rng.uniform(0.015, 0.03)))]
    if rng.random() < 0.4:  # a second shelf
        z2 = z + rng.uniform(0.18, 0.3)
        parts.append(slab((-ix, -iy, z2), (ix * 0.2, iy, z2 + 0.02)))
    return {"shelf": parts}


# --- seating -----------------------------------------------------------------------------------

def seat_body(rng: np.random.Generator) -> Body:
    seat_h = rng.uniform(0.42, 0.52)
    depth, width = rng.uniform(0.38, 0.55), rng.uniform(0.38, 0.55)
    thick = rng.uniform(0.03, 0.07)
    leg = rng.uniform(0.015, 0.03)
    inset = rng.uniform(0.01, 0.05)
    hx, hy = depth / 2, width / 2
    parts = _slab_on_legs(rng, "seat", seat_h, depth, width, thick, inset, leg)
    if rng.random() < 0.4:
        z = rng.uniform(0.1, 0.25)
        ix, iy = hx - inset, hy - inset
        parts["stretchers"] = [tube((-ix, s * iy, z), (ix, s * iy, z), leg * 0.6) for s in (-1, 1)]
        parts["stretchers"].append(tube((0, -iy, z), (0, iy, z), leg * 0.6))
    return Body(parts, {"seat_h": seat_h, "depth": depth, "width": width, "leg": leg,
                        "inset": inset})


def stool(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    if rng.random() < 0.5:
        return {}
    ix, iy = d["depth"] / 2 - d["inset"], d["width"] / 2 - d["inset"]
    z = rng.uniform(0.15, 0.3)
    corners = _corners(ix, iy)[[0, 1, 3, 2]]
    ring_ = [tube((*corners[i], z), (*corners[(i + 1) % 4], z), d["leg"] * 0.7) for i in range(4)]
    return {"footrest": ring_}


def _back(body: Body, rng: np.random.Generator) -> Parts:
    d = body.dims
    hx, hy = d["depth"] / 2, d["width"] / 2
    back_h = rng.uniform(0.3, 0.5)
    lean = rng.uniform(0.0, 0.08)
    s = d["seat_h"]
    if rng.random() < 0.5:
        return [slab((-hx, -hy, s), (-hx + 0.03, hy, s + back_h * 0.4)),
                slab((-hx - lean, -hy, s + back_h * 0.35), (-hx - lean + 0.03, hy, s + back_h))]
    slats = int(rng.integers(2, 6))
    parts = [tube((-hx + 0.015, y, s), (-hx + 0.015 - lean, y, s + back_h), d["leg"] * 0.7)
             for y in np.linspace(-hy + 0.02, hy - 0.02, slats)]
    parts.append(slab((-hx - lean, -hy, s + back_h - 0.06), (-hx - lean + 0.035, hy,
                                                            s + back_h)))
    return parts


def _arms(body: Body, rng: np.random.Generator) -> Parts:
    d = body.dims
    hx, hy = d["depth"] / 2, d["width"] / 2
    z = d["seat_h"] + rng.uniform(0.16, 0.26)
    parts: Parts = []
    for s in (-1, 1):
        y = s * (hy - 0.02)
        parts += [slab((-hx, y - 0.025, z - 0.03), (hx - rng.uniform(0.0, 0.06), y + 0.025, z)),
                  tube((hx - 0.08, y, d["seat_h"]), (hx - 0.08, y, z - 0.02), 0.015)]
    return parts


def chair(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    return {"back": _back(body, rng)}


def armchair(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    return {"back": _back(body, rng), "arms": _arms(body, rng)}


def wheelchair(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    radius = rng.uniform(0.26, 0.32)
    y = d["width"] / 2 + rng.uniform(0.04, 0.08)
    wheels: Parts = []
    for s in (-1, 1):
        wheels += spoked_wheel((-0.05, s * y, radius), Y, radius, 0.015,
                               int(rng.integers(8, 17)), 0.003, 0.03, 0.05)
    parts = {"back": _back(body, rng), "wheels": wheels}
    if rng.random() < 0.7:
        parts["arms"] = _arms(body, rng)
    return parts
