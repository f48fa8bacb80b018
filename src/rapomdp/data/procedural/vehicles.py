"""Vehicle families: cars (car, van, suv, pickup) and two-wheelers (bicycle, motorbike, scooter).

Cars share a chassis on four wheels, a bonnet and a front cabin, and differ by the rear (-x): a
sedan's lower boot, a van's tall box, an SUV's spare wheel on its back, a pickup's open bed;
from the front the cabin hides most of it. Two-wheelers share the wheels (spoked or solid,
thin or thick tyres for every class), the fork and the handlebar; they differ by what is
between the wheels (a bicycle's frame and pedals, a motorbike's engine, tank and exhaust on
+y, a scooter's floorboard and rear cover).
"""

from __future__ import annotations

import numpy as np

from rapomdp.data.procedural.body import Body, Parts
from rapomdp.data.procedural.parts import (
    disc,
    ellipsoid,
    slab,
    solid_wheel,
    spoked_wheel,
    tube,
)

X = (1.0, 0.0, 0.0)
Y = (0.0, 1.0, 0.0)


# --- cars --------------------------------------------------------------------------------------

def car_body(rng: np.random.Generator) -> Body:
    length = rng.uniform(3.6, 5.0)
    width = rng.uniform(1.6, 1.9)
    chassis = rng.uniform(0.45, 0.7)
    radius = rng.uniform(0.3, 0.38)
    clearance = radius * rng.uniform(0.4, 0.6)
    axle = length * rng.uniform(0.3, 0.36)
    hx, hy = length / 2, width / 2
    deck = clearance + chassis
    cabin_front = hx - length * rng.uniform(0.25, 0.36)
    cabin_back = length * rng.uniform(-0.08, 0.08)
    cabin_h = rng.uniform(0.42, 0.62)
    cabin_w = hy * rng.uniform(0.85, 0.95)
    parts: dict[str, Parts] = {
        "chassis": [slab((-hx, -hy, clearance), (hx, hy, deck))],
        "cabin": [slab((cabin_back, -cabin_w, deck - 0.01), (cabin_front, cabin_w, deck + cabin_h)),
                  slab((cabin_front - 0.01, -cabin_w, deck - 0.01),
                       (cabin_front + 0.25, cabin_w, deck + cabin_h * 0.45))],
        "wheels": [],
    }
    for x in (-axle, axle):
        for y in (-hy, hy):
            parts["wheels"] += solid_wheel((x, y, radius), Y, radius, radius * 0.3, 0.22)
    if rng.random() < 0.6:
        parts["lights"] = [disc((hx, s * hy * 0.7, deck - chassis * 0.3), X, 0.08, 0.03)
                           for s in (-1, 1)]
    return Body(parts, {"length": length, "width": width, "deck": deck, "cabin_back": cabin_back,
                        "cabin_h": cabin_h, "cabin_w": cabin_w})


def car(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    rear = -d["length"] * rng.uniform(0.18, 0.3)
    top = d["deck"] + d["cabin_h"]
    back = -d["length"] / 2 + rng.uniform(0.0, 0.1)
    boot = d["deck"] + d["cabin_h"] * rng.uniform(0.25, 0.5)
    parts = {"rear": [slab((rear, -d["cabin_w"], d["deck"] - 0.01), (d["cabin_back"] + 0.01,
                                                                     d["cabin_w"], top)),
                      slab((back, -d["cabin_w"], d["deck"] - 0.01),
                           (rear + 0.01, d["cabin_w"], boot))]}
    if rng.random() < 0.3:
        x = -d["length"] / 2 + 0.15
        parts["spoiler"] = [slab((x - 0.12, -d["cabin_w"], d["deck"] + 0.12),
                                 (x + 0.05, d["cabin_w"], d["deck"] + 0.16))]
    return parts


def van(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    top = d["deck"] + d["cabin_h"] * rng.uniform(1.0, 1.35)
    back = -d["length"] / 2 + rng.uniform(0.0, 0.1)
    return {"rear": [slab((back, -d["width"] / 2 * 0.97, d["deck"] - 0.01),
                          (d["cabin_back"] + 0.02, d["width"] / 2 * 0.97, top))]}


def suv(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    top = d["deck"] + d["cabin_h"] * rng.uniform(0.95, 1.05)
    back = -d["length"] / 2 + rng.uniform(0.05, 0.2)
    parts = {"rear": [slab((back, -d["cabin_w"], d["deck"] - 0.01),
                           (d["cabin_back"] + 0.02, d["cabin_w"], top))]}
    radius = rng.uniform(0.28, 0.36)
    parts["spare"] = [disc((back - 0.08, 0, d["deck"] + radius * 0.6), X, radius, 0.16)]
    return parts


def pickup(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    wall = rng.uniform(0.3, 0.45)
    t = 0.05
    back = -d["length"] / 2
    front = d["cabin_back"] - 0.05
    hy = d["cabin_w"]
    wall = min(wall, d["cabin_h"] * 0.85)
    z0, z1 = d["deck"] - 0.01, d["deck"] + wall
    return {"bed": [slab((back, -hy, z0), (front, -hy + t, z1)),
                    slab((back, hy - t, z0), (front, hy, z1)),
                    slab((back, -hy, z0), (back + t, hy, z1)),
                    slab((front - t, -hy, z0), (front, hy, z1))]}


# --- two-wheelers ------------------------------------------------------------------------------

def two_wheeler_body(rng: np.random.Generator) -> Body:
    radius = rng.uniform(0.25, 0.36)
    tyre = rng.uniform(0.015, 0.06)
    base = rng.uniform(0.95, 1.4)
    rear, front = np.array([-base / 2, 0, radius]), np.array([base / 2, 0, radius])
    parts: dict[str, Parts] = {"wheels": []}
    spoked = bool(rng.random() < 0.5)
    spokes = int(rng.integers(8, 17))
    for hub in (rear, front):
        if spoked:
            parts["wheels"] += spoked_wheel(hub, Y, radius, tyre, spokes, 0.003, 0.025, 0.1)
        else:
            parts["wheels"] += solid_wheel(hub, Y, radius, tyre, rng.uniform(0.05, 0.12))
    head = front + [-rng.uniform(0.12, 0.22), 0, rng.uniform(0.5, 0.7)]
    fork = rng.uniform(0.012, 0.025)
    half_bar = rng.uniform(0.2, 0.36)
    bar = head + [0.02, 0, rng.uniform(0.05, 0.12)]
    parts["fork"] = [tube(front + [0, s * 0.05, 0], head + [0, s * 0.03, 0], fork)
                     for s in (-1, 1)]
    parts["handlebar"] = [tube(head, bar, fork),
                          tube(bar - [0, half_bar, 0], bar + [0, half_bar, 0], 0.014)]
    return Body(parts, {"radius": radius, "base": base, "rear_x": -base / 2,
                        "front_x": base / 2, "head_x": head[0], "head_z": head[2]})


def bicycle(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    r = d["radius"]
    rear = np.array([d["rear_x"], 0, r])
    tube_r = rng.uniform(0.012, 0.02)
    bracket = np.array([d["rear_x"] + 0.42 * d["base"], 0, r - 0.04])
    seat_top = np.array([bracket[0] - 0.13, 0, d["head_z"] * rng.uniform(0.9, 1.0)])
    head_top = np.array([d["head_x"], 0, d["head_z"]])
    head_low = np.array([d["head_x"] + 0.05, 0, r + 0.2])
    frame = [tube(bracket, seat_top, tube_r), tube(bracket, head_low, tube_r),
             tube(seat_top, head_top, tube_r) if rng.random() < 0.7 else
             tube(bracket + [0.05, 0, 0.2], head_low + (head_top - head_low) * 0.3, tube_r)]
    for side in (-0.04, 0.04):
        frame += [tube(rear + [0, side, 0], bracket + [0, side, 0], tube_r * 0.7),
                  tube(rear + [0, side, 0], seat_top + [0, side, -0.05], tube_r * 0.7)]
    post = seat_top + [-0.02, 0, rng.uniform(0.06, 0.14)]
    frame += [tube(seat_top, post, tube_r * 0.8),
              ellipsoid((0.12, 0.05, 0.025), post + [0, 0, 0.02])]
    crank = rng.uniform(0.15, 0.18)
    pedals = [disc(bracket + [0, 0.06, 0], Y, rng.uniform(0.07, 0.1), 0.012),
              tube(bracket + [0, 0.07, 0], bracket + [crank * 0.7, 0.07, -crank * 0.7], 0.01),
              slab(bracket + [crank * 0.7 - 0.05, 0.07, -crank * 0.7 - 0.01],
                   bracket + [crank * 0.7 + 0.05, 0.16, -crank * 0.7 + 0.01])]
    return {"frame": frame, "pedals": pedals}


def motorbike(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    r = d["radius"]
    engine_l = d["base"] * rng.uniform(0.22, 0.32)
    engine = np.array([rng.uniform(-0.08, 0.08), 0, r + rng.uniform(0.0, 0.08)])
    engine_w = rng.uniform(0.2, 0.32)
    tank_z = d["head_z"] * rng.uniform(0.85, 1.0)
    tank = np.array([engine[0] + rng.uniform(0.08, 0.16), 0, tank_z])
    seat_l = rng.uniform(0.35, 0.5)
    parts = {
        "engine": [slab(engine - [engine_l / 2, engine_w / 2, 0.14],
                        engine + [engine_l / 2, engine_w / 2, 0.14])],
        "tank": [ellipsoid((rng.uniform(0.18, 0.26), rng.uniform(0.11, 0.16), 0.09), tank),
                 slab((tank[0] - 0.2 - seat_l, -0.11, tank_z - 0.07),
                      (tank[0] - 0.2, 0.11, tank_z + 0.01)),
                 tube((d["rear_x"], 0, r), engine - [engine_l / 2, 0, 0], 0.03),
                 tube(tank, (d["head_x"], 0, d["head_z"]), 0.03)],
        "exhaust": [tube(engine + [0, engine_w / 2 + 0.03, -0.08],
                         (d["rear_x"] - 0.05, engine_w / 2 + 0.05, r + 0.05),
                         rng.uniform(0.03, 0.045))],
    }
    return parts


def scooter(body: Body, rng: np.random.Generator) -> dict[str, Parts]:
    d = body.dims
    r = d["radius"]
    floor_z = r * rng.uniform(0.6, 0.9)
    x0, x1 = d["rear_x"] + r * 0.6, d["head_x"] - 0.02
    cover = np.array([d["rear_x"] + r * 0.2, 0, r + rng.uniform(0.12, 0.22)])
    return {
        "floor": [slab((x0, -0.13, floor_z - 0.03), (x1, 0.13, floor_z + 0.02))],
        "shield": [slab((x1 - 0.04, -0.18, floor_z), (x1, 0.18, d["head_z"] * rng.uniform(0.75,
                                                                                         0.95)))],
        "cover": [ellipsoid((r * rng.uniform(1.0, 1.4), 0.16, 0.16), cover),
                  slab((cover[0] - 0.2, -0.12, cover[2] + 0.1), (cover[0] + 0.25, 0.12,
                                                                 cover[2] + 0.18))],
    }
