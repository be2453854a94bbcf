"""Prototype lifting-cylinder test with parameter overrides (exploration only)."""

import dataclasses
import json
import math
import sys
import time
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from veragmil_suite.models.dish import DishShape
from veragmil_suite.models.foods import get_food
from veragmil_suite.models.grains import GrainPile


def run(
    food="rice",
    n=None,
    radius=0.021,
    fill_h=0.035,
    lift_speed=0.02,
    impratio=1,
    iterations=30,
    condim=3,
    mu=None,
    roll=0.0,
    tors=0.0,
    margin=0.0,
    size=None,
    aspect=None,
    density=None,
    shape=None,
    seed=0,
    timestep=1 / 240,
    solver="CG",
    noslip=0,
    timeconst=None,
    solimp=None,
    sleep=3e-3,
    max_t=8.0,
    verbose=False,
):
    f = get_food(food)
    kw = {}
    if mu is not None:
        kw["friction"] = mu
    if size is not None:
        kw["size_range_m"] = tuple(size)
    if aspect is not None:
        kw["aspect"] = tuple(aspect)
    if density is not None:
        kw["density_kg_m3"] = density
    if shape is not None:
        kw["shape"] = shape
    f = dataclasses.replace(f, **kw)
    rng = np.random.default_rng(seed)
    if n is None:
        v = f.piece_volume_m3()
        n = int(math.pi * radius**2 * fill_h * 0.55 / v)
    pile = GrainPile(f, n, rng)
    root = ET.Element("mujoco", model="cyl")
    opt = ET.SubElement(
        root,
        "option",
        timestep=repr(timestep),
        solver=solver,
        iterations=str(iterations),
        ls_iterations="10",
        cone="elliptic",
        impratio=str(impratio),
        noslip_iterations=str(noslip),
    )
    fl = ET.SubElement(opt, "flag", eulerdamp="disable")
    if sleep:
        fl.set("sleep", "enable")
        opt.set("sleep_tolerance", repr(sleep))
    world = ET.SubElement(root, "worldbody")
    ET.SubElement(
        world,
        "geom",
        name="floor",
        type="box",
        pos="0 0 -0.01",
        size="0.5 0.5 0.01",
        friction="0.01 0 0",
        contype="1",
        conaffinity="7",
    )
    tube = ET.SubElement(world, "body", name="tube", mocap="true", pos="0 0 0")
    nst, t, H = 24, 0.005, 0.25
    for k in range(nst):
        th = 2 * math.pi * k / nst
        chord = 2 * (radius + t) * math.tan(math.pi / nst) * 1.1
        ET.SubElement(
            tube,
            "geom",
            type="box",
            size=f"{t} {chord / 2} {H / 2}",
            pos=f"{(radius + t) * math.cos(th)} {(radius + t) * math.sin(th)} {H / 2 + 0.0005}",
            euler=f"0 0 {th}",
            friction="0.01 0 0",
            contype="4",
            conaffinity="2",
        )
    bodies = pile.bodies()
    for b in bodies:
        for g in b.findall("geom"):
            g.set("condim", str(condim))
            g.set("friction", f"{f.friction} {tors} {roll}")
            if margin:
                g.set("margin", repr(margin))
                g.set("gap", repr(0.0))
            if timeconst:
                g.set("solref", f"{timeconst} {f.damping_ratio}")
            if solimp:
                g.set("solimp", " ".join(map(str, solimp)))
        world.append(b)
    xml = ET.tostring(root, encoding="unicode")
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    shape_ = DishShape(
        rim_semi_axes=(radius, radius),
        floor_semi_axes=(radius, radius),
        depth=10.0,
        wall_half_thickness=t,
        floor_half_thickness=0.01,
    )
    lat = pile.lattice_qpos(shape_, rim_center=np.array([0, 0, 10.0]))
    adr = np.array([m.joint(j).qposadr[0] for j in pile.joint_names])
    d.qpos[adr[:, None] + np.arange(7)] = lat
    ids = np.array([m.body(b).id for b in pile.body_names])
    mass = m.body_mass[ids]
    thick = pile.thickness_radii
    t0 = time.time()

    def settle(tmax):
        start = d.time
        while d.time - start < tmax:
            mujoco.mj_step(m, d, nstep=24)
            v = np.linalg.norm(d.cvel[ids, 3:], axis=1)
            if not np.isfinite(v).all():
                return "nan"
            if d.time - start > 0.3 and v.max() < 0.002:
                return "rest"
        return f"vmax={v.max():.3f}"

    s1 = settle(max_t)
    top = d.xpos[ids, 2] + thick
    rxy = np.hypot(d.xpos[ids, 0], d.xpos[ids, 1])
    inner = rxy < radius - 2 * thick.max()
    # bulk: grains below 0.8*hfill in the core, over core volume... use full: mass/(pi R^2 hfill_mean)
    # surface mean by xy cells
    cell = 2 * pile.radii.mean()
    cx = np.floor(d.xpos[ids, 0] / cell).astype(int)
    cy = np.floor(d.xpos[ids, 1] / cell).astype(int)
    surf = {}
    for i in range(n):
        if inner[i]:
            k = (cx[i], cy[i])
            surf[k] = max(surf.get(k, 0), top[i])
    hmean = float(np.mean(list(surf.values())))
    bulk_vol = math.pi * radius**2 * hmean
    packing = pile.volumes_m3.sum() / bulk_vol
    bulk = mass.sum() / bulk_vol
    # lift
    lift_to = hmean + 0.02
    while d.mocap_pos[0, 2] < lift_to:
        d.mocap_pos[0, 2] += lift_speed * m.opt.timestep
        mujoco.mj_step(m, d)
    d.mocap_pos[0, 2] = 5.0
    s2 = settle(max_t)
    top = d.xpos[ids, 2] + thick
    r = np.hypot(d.xpos[ids, 0], d.xpos[ids, 1])
    bw = 2 * pile.radii.mean()
    bins = np.arange(0, r.max() + bw, bw)
    prof = []
    for lo in bins:
        sel = (r >= lo) & (r < lo + bw)
        if sel.sum():
            prof.append((lo + bw / 2, top[sel].max()))
    prof = np.array(prof)
    Hh = prof[:, 1].max()
    thickness = 2 * np.median(thick)
    beyond = np.flatnonzero(prof[:, 1] < 1.5 * thickness)
    Rb = prof[beyond[0], 0] if beyond.size else prof[-1, 0]
    ang_hb = math.degrees(math.atan2(Hh - thickness / 2, Rb))
    sel = (prof[:, 1] > 0.2 * Hh) & (prof[:, 1] < 0.85 * Hh) & (prof[:, 0] <= Rb)
    ang_fit = float("nan")
    if sel.sum() >= 3:
        k = np.polyfit(prof[sel, 0], prof[sel, 1], 1)[0]
        ang_fit = math.degrees(math.atan(-k))
    out = dict(
        food=food,
        n=n,
        mass_mg=float(mass.mean() * 1e6),
        packing=round(packing, 3),
        bulk=round(bulk / 1000, 3),
        hfill_cm=round(hmean * 100, 2),
        H_cm=round(Hh * 100, 2),
        Rb_cm=round(Rb * 100, 2),
        ang_hb=round(ang_hb, 1),
        ang_fit=round(ang_fit, 1),
        s1=s1,
        s2=s2,
        sim_t=round(d.time, 2),
        wall=round(time.time() - t0, 1),
        maxspeed=float(np.linalg.norm(d.cvel[ids, 3:], axis=1).max()),
    )
    if verbose:
        out["profile"] = prof.round(4).tolist()
    return out


if __name__ == "__main__":
    kw = json.loads(sys.argv[1]) if len(sys.argv) > 1 else {}
    print(json.dumps({**kw, **run(**kw)}), flush=True)
