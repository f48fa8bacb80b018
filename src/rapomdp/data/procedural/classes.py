"""The procedural classes: parametric models that vary in proportions and parts.

Classes deliberately share parts so that single views are ambiguous from some directions:
bicycles, motorbikes, wheelchairs and cars share wheels; cups and mugs share their bodies (a mug
seen from the side away from its handle looks like a cup); teapots and kettles share bodies and
spouts; bottles and vases share profiles; eyeglass rims and scissor handles are rings like thin
tyres; chairs and tables share legs. Every model stands upright, long side along x, in metres at
roughly real scale (the dataset stage normalises the size).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import trimesh

from rapomdp.data.procedural.parts import (
    assemble,
    box,
    disc,
    ellipsoid,
    revolved,
    ring,
    solid_wheel,
    spoked_wheel,
    tube,
    vessel,
)

Parts = list[trimesh.Trimesh]
Y = (0.0, 1.0, 0.0)
Z = (0.0, 0.0, 1.0)
X = (1.0, 0.0, 0.0)


def bicycle(rng: np.random.Generator) -> Parts:
    radius = rng.uniform(0.30, 0.36)
    tyre = rng.uniform(0.012, 0.02)
    base = rng.uniform(0.95, 1.12)
    frame_h = rng.uniform(0.42, 0.56)
    tube_r = rng.uniform(0.012, 0.02)
    rear, front = np.array([-base / 2, 0, radius]), np.array([base / 2, 0, radius])
    spokes = int(rng.integers(8, 17))
    parts = []
    for hub in (rear, front):
        parts += spoked_wheel(hub, Y, radius, tyre, spokes, 0.003, 0.025, 0.1)
    bracket = np.array([rear[0] + 0.42 * base, 0, radius - 0.04])
    seat_top = np.array([bracket[0] - 0.13, 0, radius + frame_h])
    head_top = np.array([front[0] - 0.2, 0, radius + frame_h * rng.uniform(0.9, 1.0)])
    head_low = np.array([front[0] - 0.14, 0, radius + 0.2])
    step_through = rng.random() < 0.3
    top_end = head_low + (head_top - head_low) * 0.3 if step_through else head_top
    parts += [
        tube(bracket, seat_top, tube_r),
        tube(bracket, head_low, tube_r),
        tube(seat_top if not step_through else bracket + [0.05, 0, 0.25], top_end, tube_r),
        tube(head_low, head_top, tube_r * 1.2),
    ]
    for side in (-0.04, 0.04):
        parts += [
            tube(rear + [0, side, 0], bracket + [0, side, 0], tube_r * 0.7),
            tube(rear + [0, side, 0], seat_top + [0, side, -0.05], tube_r * 0.7),
            tube(front + [0, side, 0], head_low + [0, side, 0], tube_r * 0.8),
        ]
    post_top = seat_top + [-0.02, 0, rng.uniform(0.06, 0.14)]
    parts += [
        tube(seat_top, post_top, tube_r * 0.8),
        ellipsoid((0.12, 0.05, 0.025), post_top + [0, 0, 0.02]),
        disc(bracket, Y, rng.uniform(0.07, 0.1), 0.012),
    ]
    stem = head_top + [0.02, 0, rng.uniform(0.05, 0.12)]
    half_bar = rng.uniform(0.2, 0.28)
    parts += [tube(head_top, stem, tube_r), tube(stem - [0, half_bar, 0], stem + [0, half_bar, 0],
                                                  tube_r * 0.8)]
    return parts


def motorbike(rng: np.random.Generator) -> Parts:
    radius = rng.uniform(0.29, 0.34)
    tyre = rng.uniform(0.045, 0.07)
    base = rng.uniform(1.25, 1.5)
    rear, front = np.array([-base / 2, 0, radius]), np.array([base / 2, 0, radius])
    parts = []
    for hub in (rear, front):
        parts += solid_wheel(hub, Y, radius, tyre, rng.uniform(0.08, 0.14))
    engine_l = rng.uniform(0.32, 0.46)
    engine = np.array([rng.uniform(-0.08, 0.08), 0, radius + rng.uniform(0.02, 0.1)])
    parts.append(box((engine_l, rng.uniform(0.26, 0.36), rng.uniform(0.26, 0.36)), engine))
    tank_h = radius + rng.uniform(0.4, 0.5)
    tank = np.array([engine[0] + rng.uniform(0.08, 0.18), 0, tank_h])
    parts.append(ellipsoid((rng.uniform(0.2, 0.28), rng.uniform(0.12, 0.17), 0.1), tank))
    seat_l = rng.uniform(0.38, 0.55)
    parts.append(box((seat_l, rng.uniform(0.2, 0.28), 0.08),
                     (tank[0] - 0.22 - seat_l / 2, 0, tank_h - 0.02)))
    head = np.array([front[0] - 0.22, 0, radius + rng.uniform(0.52, 0.62)])
    for side in (-0.08, 0.08):
        parts += [
            tube(front + [0, side, 0], head + [0, side, 0], 0.025),
            tube(rear + [0, side, 0], engine + [-engine_l / 2, side, 0], 0.03),
        ]
    half_bar = rng.uniform(0.3, 0.38)
    bar = head + [0.02, 0, 0.08]
    parts += [tube(head, bar, 0.025), tube(bar - [0, half_bar, 0], bar + [0, half_bar, 0], 0.016)]
    parts.append(tube(engine + [0, 0.2, -0.05], rear + [-0.1, 0.2, 0.08], rng.uniform(0.035, 0.05)))
    if rng.random() < 0.6:
        parts.append(ellipsoid((0.06, 0.08, 0.08), head + [0.1, 0, -0.02]))
    return parts


def car(rng: np.random.Generator) -> Parts:
    length = rng.uniform(3.6, 4.6)
    width = rng.uniform(1.6, 1.85)
    height = rng.uniform(0.5, 0.7)
    radius = rng.uniform(0.3, 0.36)
    clearance = radius * rng.uniform(0.45, 0.6)
    parts = [box((length, width, height), (0, 0, clearance + height / 2))]
    cabin_l = length * rng.uniform(0.4, 0.6)
    cabin_h = rng.uniform(0.42, 0.55)
    parts.append(box((cabin_l, width * rng.uniform(0.82, 0.92), cabin_h),
                     (length * rng.uniform(-0.12, 0.05), 0, clearance + height + cabin_h / 2)))
    for x in (-length * 0.32, length * 0.32):
        for y in (-width / 2, width / 2):
            parts += solid_wheel((x, y, radius), Y, radius, radius * 0.3, 0.2)
    return parts


def wheelchair(rng: np.random.Generator) -> Parts:
    seat_h = rng.uniform(0.46, 0.52)
    seat_w = rng.uniform(0.4, 0.48)
    seat_d = rng.uniform(0.4, 0.46)
    radius = rng.uniform(0.27, 0.32)
    parts = [box((seat_d, seat_w, 0.05), (0, 0, seat_h))]
    back_h = rng.uniform(0.38, 0.5)
    parts.append(box((0.04, seat_w, back_h), (-seat_d / 2, 0, seat_h + back_h / 2), pitch=-0.15))
    half = seat_w / 2 + 0.06
    for side in (-1, 1):
        y = side * half
        parts += spoked_wheel((-0.08, y, radius), Y, radius, 0.015, int(rng.integers(10, 19)),
                              0.003, 0.03, 0.05)
        caster = np.array([seat_d / 2 + 0.05, side * (seat_w / 2 - 0.02), 0.07])
        parts += solid_wheel(caster, Y, 0.07, 0.02, 0.03)
        parts += [
            tube(caster + [0, 0, 0.07], (seat_d / 2, y * 0.9, seat_h), 0.012),
            tube((-seat_d / 2, y * 0.9, seat_h), (seat_d / 2, y * 0.9, seat_h), 0.012),
            tube((-seat_d / 2 - 0.04, y * 0.9, seat_h), (-seat_d / 2 - 0.06, y * 0.9,
                                                        seat_h + back_h + 0.05), 0.012),
        ]
        if rng.random() < 0.7:
            parts.append(box((seat_d * 0.8, 0.04, 0.03), (0, y * 0.9, seat_h + 0.22)))
    return parts


def _pot_body(rng: np.random.Generator, belly: float, height: float) -> trimesh.Trimesh:
    profile = [
        (0.0, 0.0), (belly * 0.62, 0.0), (belly * 0.95, height * 0.25), (belly, height * 0.45),
        (belly * rng.uniform(0.75, 0.88), height * 0.85), (belly * 0.55, height),
        (belly * 0.5, height * 1.04), (0.0, height * 1.06),
    ]
    return revolved(profile)


def teapot(rng: np.random.Generator) -> Parts:
    belly = rng.uniform(0.08, 0.11)
    height = belly * rng.uniform(1.1, 1.5)
    parts = [_pot_body(rng, belly, height)]
    parts.append(ellipsoid((0.015, 0.015, 0.012), (0, 0, height * 1.08)))
    tip = np.array([belly + rng.uniform(0.06, 0.1), 0, height * rng.uniform(0.85, 1.05)])
    mid = np.array([belly + 0.02, 0, height * 0.55])
    parts += [tube((belly * 0.7, 0, height * 0.3), mid, 0.016), tube(mid, tip, 0.01)]
    parts.append(ring((-belly * 0.98, 0, height * 0.55), Y, height * rng.uniform(0.25, 0.32),
                      0.009, stretch=(rng.uniform(0.8, 1.1), 1.0, 1.0)))
    return parts


def kettle(rng: np.random.Generator) -> Parts:
    base = rng.uniform(0.08, 0.1)
    height = base * rng.uniform(1.6, 2.1)
    top = base * rng.uniform(0.7, 0.92)
    profile = [(0.0, 0.0), (base, 0.0), (base, height * 0.1), (top, height),
               (top * 0.5, height * 1.03), (0.0, height * 1.05)]
    parts = [revolved(profile)]
    parts.append(ring((0, 0, height), Y, top * rng.uniform(0.55, 0.75), 0.012,
                      stretch=(1.0, 1.0, rng.uniform(0.9, 1.4))))
    parts.append(tube((base * 0.8, 0, height * 0.45), (base + rng.uniform(0.03, 0.06), 0,
                                                       height * 0.75), 0.012))
    if rng.random() < 0.5:
        parts.append(disc((0, 0, 0.006), Z, base * 1.15, 0.012))
    return parts


def _cup_body(rng: np.random.Generator, radius: float, taper: float, height: float):
    outer = [(radius, 0.0), (radius * (1 + taper) / 2, height / 2), (radius * taper, height)]
    return vessel(outer, wall=radius * 0.08, floor=height * 0.08)


def cup(rng: np.random.Generator) -> Parts:
    radius = rng.uniform(0.035, 0.045)
    return [_cup_body(rng, radius, rng.uniform(1.0, 1.25), radius * rng.uniform(2.0, 2.8))]


def mug(rng: np.random.Generator) -> Parts:
    radius = rng.uniform(0.038, 0.048)
    taper = rng.uniform(0.95, 1.12)
    height = radius * rng.uniform(2.0, 2.6)
    parts = [_cup_body(rng, radius, taper, height)]
    grip = height * rng.uniform(0.25, 0.33)
    parts.append(ring((radius * (1 + taper) / 2 + grip * 0.4, 0, height * 0.52), Y, grip, 0.007,
                      stretch=(rng.uniform(0.6, 0.9), 1.0, 1.0)))
    return parts


def bottle(rng: np.random.Generator) -> Parts:
    radius = rng.uniform(0.03, 0.045)
    body = radius * rng.uniform(3.0, 4.5)
    neck_r = radius * rng.uniform(0.3, 0.42)
    shoulder = radius * rng.uniform(0.8, 1.6)
    neck = radius * rng.uniform(1.0, 1.8)
    cap = neck_r * 1.15
    profile = [
        (0.0, 0.0), (radius, 0.0), (radius, body), (neck_r, body + shoulder),
        (neck_r, body + shoulder + neck), (cap, body + shoulder + neck),
        (cap, body + shoulder + neck + 0.02), (0.0, body + shoulder + neck + 0.02),
    ]
    return [revolved(profile)]


def vase(rng: np.random.Generator) -> Parts:
    belly = rng.uniform(0.05, 0.07)
    height = belly * rng.uniform(3.0, 4.2)
    neck = belly * rng.uniform(0.35, 0.55)
    outer = [
        (belly * 0.6, 0.0), (belly, height * rng.uniform(0.25, 0.4)), (neck, height * 0.8),
        (neck * rng.uniform(1.2, 1.6), height),
    ]
    return [vessel(outer, wall=neck * 0.15, floor=height * 0.1)]


def eyeglasses(rng: np.random.Generator) -> Parts:
    lens_h = rng.uniform(0.018, 0.024)
    lens_w = lens_h * rng.uniform(1.1, 1.5)
    bridge = rng.uniform(0.014, 0.022)
    rim = rng.uniform(0.0025, 0.0035)
    centre_z = lens_h + 0.004
    temple = rng.uniform(0.12, 0.145)
    parts = []
    for side in (-1, 1):
        c = np.array([0.0, side * (bridge / 2 + lens_w), centre_z])
        parts.append(ring(c, X, lens_h, rim, stretch=(1.0, lens_w / lens_h, 1.0)))
        if rng.random() < 0.4:
            parts.append(disc(c, X, lens_h * 0.95, 0.002))
        hinge = c + [0, side * lens_w, lens_h * 0.4]
        back = hinge + [-temple, side * 0.01, 0]
        ear = (back[0] - 0.025, back[1], rim)
        parts += [tube(hinge, back, 0.002, 6), tube(back, ear, 0.002, 6)]
    parts.append(tube((0, -bridge / 2 - 0.002, centre_z + lens_h * 0.5),
                      (0, bridge / 2 + 0.002, centre_z + lens_h * 0.5), 0.002, 6))
    return parts


def scissors(rng: np.random.Generator) -> Parts:
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
    return parts


def _legs(corners: np.ndarray, top: float, radius: float, square: bool) -> Parts:
    if square:
        return [box((radius * 2, radius * 2, top), (x, y, top / 2)) for x, y in corners]
    return [tube((x, y, 0.0), (x, y, top), radius) for x, y in corners]


def chair(rng: np.random.Generator) -> Parts:
    seat_h = rng.uniform(0.42, 0.48)
    depth, width = rng.uniform(0.4, 0.5), rng.uniform(0.4, 0.5)
    square = bool(rng.random() < 0.5)
    leg = rng.uniform(0.015, 0.025)
    inset = 0.03
    corners = np.array([[sx * (depth / 2 - inset), sy * (width / 2 - inset)]
                        for sx in (-1, 1) for sy in (-1, 1)])
    parts = [box((depth, width, 0.04), (0, 0, seat_h))] + _legs(corners, seat_h, leg, square)
    back_h = rng.uniform(0.35, 0.5)
    if rng.random() < 0.5:
        parts.append(box((0.03, width, back_h), (-depth / 2, 0, seat_h + back_h / 2), pitch=-0.1))
    else:
        for y in np.linspace(-width / 2 + inset, width / 2 - inset, int(rng.integers(3, 6))):
            parts.append(tube((-depth / 2, y, seat_h), (-depth / 2 - 0.04, y, seat_h + back_h),
                              leg * 0.7))
        parts.append(box((0.04, width, 0.05), (-depth / 2 - 0.04, 0, seat_h + back_h)))
    return parts


def table(rng: np.random.Generator) -> Parts:
    height = rng.uniform(0.7, 0.76)
    if rng.random() < 0.3:
        radius = rng.uniform(0.4, 0.55)
        return [disc((0, 0, height), Z, radius, 0.035), tube((0, 0, 0.02), (0, 0, height), 0.04),
                disc((0, 0, 0.015), Z, radius * 0.5, 0.03)]
    length, width = rng.uniform(0.8, 1.4), rng.uniform(0.6, 0.9)
    leg = rng.uniform(0.02, 0.035)
    inset = rng.uniform(0.03, 0.1)
    corners = np.array([[sx * (length / 2 - inset), sy * (width / 2 - inset)]
                        for sx in (-1, 1) for sy in (-1, 1)])
    return [box((length, width, 0.035), (0, 0, height))] + _legs(corners, height, leg,
                                                                 bool(rng.random() < 0.5))


CLASS_BUILDERS: dict[str, Callable[[np.random.Generator], Parts]] = {
    "bicycle": bicycle,
    "motorbike": motorbike,
    "car": car,
    "wheelchair": wheelchair,
    "teapot": teapot,
    "kettle": kettle,
    "cup": cup,
    "mug": mug,
    "bottle": bottle,
    "vase": vase,
    "eyeglasses": eyeglasses,
    "scissors": scissors,
    "chair": chair,
    "table": table,
}

PROCEDURAL_CLASSES: tuple[str, ...] = tuple(CLASS_BUILDERS)


def generate_model(class_name: str, seed: int, index: int) -> trimesh.Trimesh:
    """Model ``index`` of a procedural class; the same (seed, class, index) gives the same mesh."""
    if class_name not in CLASS_BUILDERS:
        raise KeyError(
            f"unknown procedural class '{class_name}'; classes are: {', '.join(CLASS_BUILDERS)}"
        )
    if index < 0:
        raise ValueError(f"model index must be non-negative, got {index}")
    key = int.from_bytes(class_name.encode()[:8].ljust(8, b"\0"), "little")
    rng = np.random.default_rng([seed, key, index])
    mesh = assemble(CLASS_BUILDERS[class_name](rng))
    mesh.vertices[:, 2] -= mesh.vertices[:, 2].min()
    return mesh
