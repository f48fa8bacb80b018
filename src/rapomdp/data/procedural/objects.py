"""Other families: panels (monitor, television, picture frame) and small things (eyeglasses,
sunglasses, scissors).

Panels share an upright slab facing +x and differ by the front's relief (a monitor's deep bezel,
a picture's wide raised frame) and by what holds them up (a monitor's neck and back housing at
-x, a television's two feet, a frame's easel strut at -x): seen edge-on they are alike.
Eyeglass rims and scissor handles are the same thin rings; sunglasses always hold lenses, and
wider ones.
"""

from __future__ import annotations

import numpy as np

from rapomdp.data.procedural.body import Body, Parts
from rapomdp.data.procedural.parts import box, disc, ring, slab, tube

X = (1.0, 0.0, 0.0)
Z = (0.0, 0.0, 1.0)


# --- panels ------------------------------------------------------------------------------------

def panel_body(rng: np.random.Generator) -> Body:
    width = rng.uniform(0.45, 1.1)
    height = width * rng.uniform(0.5, 0.85)
    thick = rng.uniform(0.02, 0.05)
    z0 = rng.uniform(0.06, 0.2)
    hx, hy = thick / 2, width / 2
    return Body({"panel": [slab((-hx, -hy, z0), (hx, hy, z0 + height))]},
                {"width": width, "height": height, "thick": thick, "z0": z0})


def _frame(d: dict[str, float], border: float, relief: float) -> Parts:
    hx, hy, z0, z1 = d["thick"] / 2, d["width"] / 2, d["z0"], d["z0"] + d["height"]
    x1 = hx + relief
    return [slab((hx - 0.005, -hy, z0), (x1, -hy + border, z1)),
            slab((hx - 0.005, hy - border, z0), (x1, hy, z1)),
            slab((hx - 0.005, -hy, z0), (x1, hy, z0 + border)),
            slab((hx - 0.005, -hy, z1 - border), (x1, hy, z1))]


def monitor(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    hx = d["thick"] / 2
    housing = (rng.uniform(0.04, 0.1), d["width"] * rng.uniform(0.4, 0.7),
               d["height"] * rng.uniform(0.4, 0.7))
    centre_z = d["z0"] + d["height"] * 0.5
    foot = rng.uniform(0.12, 0.22)
    return {
        "bezel": _frame(d, rng.uniform(0.015, 0.04), rng.uniform(0.008, 0.015)),
        "housing": [box(housing, (-hx - housing[0] / 2 + 0.002, 0, centre_z))],
        "stand": [slab((-hx - housing[0] * 0.7, -0.03, 0.01), (-hx - housing[0] * 0.3, 0.03,
                                                                centre_z)),
                  slab((-foot, -foot * 0.8, 0.0), (foot * 0.6, foot * 0.8, 0.015))],
    }


def television(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    hy = d["width"] / 2
    spread = hy * rng.uniform(0.5, 0.85)
    depth = rng.uniform(0.12, 0.22)
    feet: Parts = []
    for s in (-1, 1):
        feet += [slab((-depth / 2, s * spread - 0.02, 0.0), (depth / 2, s * spread + 0.02, 0.015)),
                 slab((-0.01, s * spread - 0.015, 0.0), (0.01, s * spread + 0.015,
                                                          d["z0"] + 0.05))]
    parts = {"bezel": _frame(d, rng.uniform(0.006, 0.015), rng.uniform(0.002, 0.005)),
             "feet": feet}
    if rng.random() < 0.3:
        parts["housing"] = [slab((-d["thick"] / 2 - 0.03, -hy * 0.5, d["z0"] + d["height"] * 0.2),
                                 (-d["thick"] / 2 + 0.002, hy * 0.5, d["z0"] + d["height"] * 0.7))]
    return parts


def picture_frame(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    hx, z0 = d["thick"] / 2, d["z0"]
    top = z0 + d["height"] * rng.uniform(0.6, 0.8)
    foot = -hx - d["height"] * rng.uniform(0.35, 0.55)
    return {
        "frame": _frame(d, d["width"] * rng.uniform(0.06, 0.14), rng.uniform(0.02, 0.04)),
        "easel": [tube((-hx, 0, top), (foot, 0, 0.01), rng.uniform(0.01, 0.018), 6),
                  slab((-0.03, -d["width"] * 0.4, 0.0), (hx + 0.03, d["width"] * 0.4, z0 + 0.01))],
    }


# --- small things ------------------------------------------------------------------------------

def small_body(rng: np.random.Generator) -> Body:
    """Eyeglasses and scissors share nothing but thin rings: an empty body."""
    return Body({})


def eyeglasses(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    return {"glasses": _glasses(rng, 0.4, 0.018)}


def sunglasses(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    return {"glasses": _glasses(rng, 1.0, 0.022)}


def _glasses(rng: np.random.Generator, lenses: float, lens_m: float) -> Parts:
    """Two rims on a bridge and two temples; each rim holds a lens with probability
    ``lenses``."""
    lens_h = rng.uniform(lens_m, lens_m * 1.33)
    lens_w = lens_h * rng.uniform(1.1, 1.5)
    bridge = rng.uniform(0.014, 0.022)
    rim = rng.uniform(0.0025, 0.0035)
    centre_z = lens_h + 0.004
    temple = rng.uniform(0.12, 0.145)
    parts: Parts = []
    for side in (-1, 1):
        c = np.array([0.0, side * (bridge / 2 + lens_w), centre_z])
        parts.append(ring(c, X, lens_h, rim, stretch=(1.0, lens_w / lens_h, 1.0)))
        if rng.random() < lenses:
            parts.append(disc(c, X, lens_h * 0.95, 0.002))
        hinge = c + [0, side * lens_w, lens_h * 0.4]
        back = hinge + [-temple, side * 0.01, 0]
        ear = (back[0] - 0.025, back[1], rim)
        parts += [tube(hinge, back, 0.002, 6), tube(back, ear, 0.002, 6)]
    parts.append(tube((0, -bridge / 2 - 0.002, centre_z + lens_h * 0.5),
                      (0, bridge / 2 + 0.002, centre_z + lens_h * 0.5), 0.002, 6))
    return parts


def scissors(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    blade = rng.uniform(0.08, 0.12)
    opening = np.radians(rng.uniform(4.0, 35.0))
    thickness = 0.003
    parts = [disc((0, 0, thickness * 2), Z, 0.006, thickness * 4)]
    for side, z in ((-1, thickness), (1, thickness * 3)):
        angle = side * opening / 2
        direction = np.array([np.cos(angle), np.sin(angle), 0.0])
        parts.append(box((blade, rng.uniform(0.008, 0.014), thickness),
                         direction * blade / 2 + [0, 0, z], yaw=angle))
        grip_r = rng.uniform(0.013, 0.02)
        hold = -direction * rng.uniform(0.035, 0.05)
        handle = np.array([hold[0], -hold[1] * 1.4, z])
        parts.append(ring(handle, Z, grip_r, 0.003, stretch=(rng.uniform(1.0, 1.5), 1.0, 1.0)))
        parts.append(tube((0, 0, z), handle + [grip_r * 0.8, 0, 0], 0.003, 6))
    return {"scissors": parts}
