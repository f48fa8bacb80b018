"""Vessel families: cups (cup, mug, jug, beaker), pots (teapot, kettle, saucepan) and bottles
(bottle, vase, jar, amphora).

Cups share an open body: the mug's handle is on the +x side, the jug's on -x with a pouring lip
on +x, the beaker has the lip alone, so each looks like a cup from the side away from its
handle. Pots share a closed belly and
differ by spout and handle (teapot: a long spout at +x and a side handle at -x; kettle: a short
high spout and a handle over the lid; saucepan: a long handle at -x). Bottles share a belly and
shoulder and differ by what is on top (a capped neck, an open flared neck whose cavity is seen
from above, a lidded wide mouth, two side handles).
"""

from __future__ import annotations

import numpy as np

from rapomdp.data.procedural.body import Body, Parts
from rapomdp.data.procedural.parts import disc, ellipsoid, revolved, ring, tube, vessel

Y = (0.0, 1.0, 0.0)
Z = (0.0, 0.0, 1.0)


# --- cups --------------------------------------------------------------------------------------

def cup_body(rng: np.random.Generator) -> Body:
    radius = rng.uniform(0.035, 0.055)
    taper = rng.uniform(0.85, 1.3)
    height = radius * rng.uniform(1.5, 2.8)
    belly = rng.uniform(0.95, 1.12)
    outer = [(radius, 0.0), (radius * (1 + taper) / 2 * belly, height / 2),
             (radius * taper, height)]
    parts: dict[str, Parts] = {"cup": [vessel(outer, wall=radius * 0.08, floor=height * 0.08)]}
    if rng.random() < 0.3:
        parts["rim"] = [ring((0, 0, height), Z, radius * taper - radius * 0.03, radius * 0.05)]
    if rng.random() < 0.2:
        parts["saucer"] = [disc((0, 0, -0.004), Z, radius * rng.uniform(1.6, 2.0), 0.008)]
    mid = radius * (1 + taper) / 2 * belly
    return Body(parts, {"radius": radius, "top": radius * taper, "mid": mid, "height": height})


def _cup_handle(body: Body, rng: np.random.Generator, side: float) -> Parts:
    d = body.dims
    grip = d["height"] * rng.uniform(0.22, 0.33)
    thick = rng.uniform(0.006, 0.011)
    centre = (side * (d["mid"] + grip * 0.35), 0.0, d["height"] * rng.uniform(0.45, 0.6))
    return [ring(centre, Y, grip, thick, stretch=(rng.uniform(0.6, 0.95), 1.0, 1.0))]


def cup(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    return {}


def mug(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    return {"handle": _cup_handle(body, rng, 1.0)}


def jug(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    top, h = d["top"], d["height"]
    lip = rng.uniform(0.012, 0.025)
    return {"handle": _cup_handle(body, rng, -1.0),
            "lip": [tube((top * 0.7, 0, h * 0.86), (top + lip, 0, h * 1.02), rng.uniform(0.008,
                                                                                       0.012), 8)]}


def beaker(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    top, h = d["top"], d["height"]
    lip = rng.uniform(0.01, 0.02)
    return {"lip": [tube((top * 0.7, 0, h * 0.88), (top + lip, 0, h * 1.03),
                         rng.uniform(0.007, 0.011), 8)]}


# --- pots --------------------------------------------------------------------------------------

def pot_body(rng: np.random.Generator) -> Body:
    belly = rng.uniform(0.07, 0.11)
    height = belly * rng.uniform(0.9, 1.6)
    shoulder = rng.uniform(0.7, 0.95)
    neck = rng.uniform(0.45, 0.75)
    profile = [
        (0.0, 0.0), (belly * rng.uniform(0.55, 0.8), 0.0), (belly * 0.95, height * 0.25),
        (belly, height * 0.45), (belly * shoulder, height * 0.85), (belly * neck, height),
        (belly * neck * 0.92, height * 1.04), (0.0, height * 1.06),
    ]
    parts: dict[str, Parts] = {"pot": [revolved(profile)]}
    if rng.random() < 0.8:
        parts["knob"] = [ellipsoid((0.015, 0.015, 0.012), (0, 0, height * 1.07))]
    return Body(parts, {"belly": belly, "height": height, "neck": belly * neck})


def teapot(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    b, h = body.dims["belly"], body.dims["height"]
    tip = np.array([b + rng.uniform(0.06, 0.1), 0, h * rng.uniform(0.85, 1.05)])
    mid = np.array([b + 0.02, 0, h * 0.55])
    return {
        "spout": [tube((b * 0.7, 0, h * 0.3), mid, rng.uniform(0.013, 0.02)),
                  tube(mid, tip, rng.uniform(0.008, 0.012))],
        "handle": [ring((-b * 0.98, 0, h * 0.55), Y, h * rng.uniform(0.25, 0.32), 0.009,
                        stretch=(rng.uniform(0.8, 1.1), 1.0, 1.0))],
    }


def kettle(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    b, h, neck = body.dims["belly"], body.dims["height"], body.dims["neck"]
    if rng.random() < 0.5:  # a handle over the lid
        handle = ring((0, 0, h * 1.0), Y, neck * rng.uniform(0.8, 1.2), 0.01,
                      stretch=(1.0, 1.0, rng.uniform(0.9, 1.4)))
    else:  # a tall side handle at -x, as a teapot's
        handle = ring((-b * 0.95, 0, h * 0.6), Y, h * rng.uniform(0.3, 0.38), 0.01,
                      stretch=(rng.uniform(0.6, 0.9), 1.0, 1.0))
    return {
        "spout": [tube((b * 0.7, 0, h * 0.55), (b + rng.uniform(0.02, 0.045), 0, h * 0.85),
                       rng.uniform(0.01, 0.014))],
        "handle": [handle],
    }


def saucepan(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    b, h = body.dims["belly"], body.dims["height"]
    z = h * rng.uniform(0.6, 0.8)
    length = rng.uniform(0.12, 0.2)
    parts = {"handle": [tube((-b * 0.8, 0, z), (-b - length, 0, z + length * rng.uniform(0, 0.1)),
                             rng.uniform(0.009, 0.013))]}
    if rng.random() < 0.3:
        parts["helper"] = [ring((b + 0.01, 0, z), Z, 0.02, 0.005, stretch=(1.0, 1.3, 1.0))]
    return parts


# --- bottles -----------------------------------------------------------------------------------

def bottle_body(rng: np.random.Generator) -> Body:
    radius = rng.uniform(0.035, 0.065)
    body_h = radius * rng.uniform(2.0, 4.0)
    shoulder = radius * rng.uniform(0.5, 1.5)
    top_r = radius * rng.uniform(0.25, 0.45)
    profile = [
        (0.0, 0.0), (radius * rng.uniform(0.8, 1.0), 0.0), (radius, body_h * 0.1),
        (radius * rng.uniform(0.85, 1.1), body_h), (top_r, body_h + shoulder),
        (0.0, body_h + shoulder),
    ]
    return Body({"belly": [revolved(profile)]},
                {"radius": radius, "shoulder_z": body_h + shoulder, "top_r": top_r,
                 "body_h": body_h})


def bottle(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    neck_r = d["top_r"] * rng.uniform(0.8, 1.0)
    z0 = d["shoulder_z"] - 0.005
    z1 = z0 + d["radius"] * rng.uniform(0.8, 1.8)
    cap = neck_r * 1.15
    return {"neck": [revolved([(0.0, z0), (neck_r, z0), (neck_r, z1), (cap, z1), (cap, z1 + 0.02),
                               (0.0, z1 + 0.02)])]}


def vase(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    neck_r = d["top_r"] * rng.uniform(1.0, 1.3)
    z0 = d["shoulder_z"] - d["radius"] * 0.6
    length = d["radius"] * rng.uniform(0.8, 1.8)
    flare = neck_r * rng.uniform(1.2, 1.7)
    outer = [(neck_r, 0.0), (neck_r, length * 0.7), (flare, length)]
    return {"neck": [vessel(outer, wall=neck_r * 0.2, floor=0.004, centre=(0, 0, z0))]}


def jar(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    mouth = d["radius"] * rng.uniform(0.65, 0.85)
    z0 = d["shoulder_z"] - d["radius"] * 0.5
    z1 = d["shoulder_z"] + d["radius"] * rng.uniform(0.1, 0.3)
    lid = mouth * rng.uniform(1.02, 1.12)
    parts = {"mouth": [revolved([(0.0, z0), (mouth, z0), (mouth, z1), (0.0, z1)])],
             "lid": [disc((0, 0, z1 + 0.008), Z, lid, 0.016)]}
    if rng.random() < 0.5:
        parts["lid"].append(ellipsoid((0.012, 0.012, 0.01), (0, 0, z1 + 0.02)))
    return parts


def amphora(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    neck = bottle(body, rng)["neck"]
    grip = d["radius"] * rng.uniform(0.45, 0.7)
    z = d["shoulder_z"] - d["radius"] * rng.uniform(0.1, 0.4)
    handles = [ring((0, s * (d["top_r"] + grip * 0.6), z), (1.0, 0.0, 0.0), grip, 0.006,
                    stretch=(1.0, rng.uniform(0.6, 0.9), 1.0)) for s in (-1, 1)]
    return {"neck": neck, "handles": handles}
