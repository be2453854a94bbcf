"""Settled piles: grains dropped into the bowl and run until still, once per pile model, then reused.

Settling takes 1.5-4 s of simulated time (seconds of wall time), far too long for every reset. A pile is settled
in a small model of its own (table, bowl, grains: the robot does not take part) and the result, relative to the
bowl, is kept in memory and on disk, keyed by that model's XML and the MuJoCo version. A settled pile moved or
turned rigidly on the flat table is still settled, so one settled pile serves every bowl position.

Settling is deterministic on one CPU but not across CPUs (MuJoCo's floating point differs between instruction sets,
and thousands of contact steps amplify it), so a worker on another machine would settle other piles. A worker that
runs pieces for a driver (a Ray task) is therefore handed the driver's piles (use_shipped_piles) and settles none
itself: every agent meets the same piles wherever its episodes run.
"""

from __future__ import annotations

import hashlib
import os
import weakref
import xml.etree.ElementTree as ET
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from veragmil_suite.environments import pile_cache
from veragmil_suite.models import contact_groups
from veragmil_suite.models.bowl import Bowl
from veragmil_suite.models.grains import GrainPile

SETTLE_SPEED_M_S = 0.002  # a pile whose fastest grain is slower than this is at rest...
# ...for this long, no grain moving further than SETTLE_DRIFT_M meanwhile: a slow speed at one instant is not rest (a
# calibrated pasta piece leaning on the wall crept at 0.8 mm/s, then slid 5 mm at 9 cm/s)
SETTLE_HOLD_S = 0.5
SETTLE_DRIFT_M = 0.0005
SETTLE_MIN_S = 0.5  # simulated time always run (grains start in the air)
SETTLE_MAX_S = 6.0  # give up waiting for rest after this much simulated time
SETTLE_CHECK_EVERY_S = 0.1
SETTLE_RETRIES = 3  # times a grain that bounced out of the bowl is dropped back in
SETTLE_VERSION = "5"  # part of the cache key: bump when settling, or the lattice it starts from, changes


@dataclass
class SettledPile:
    """A pile at rest, in the bowl's frame at the origin of the table top.

    Attributes:
        bowl_qpos: (7,) the bowl's free-joint pose (pos, wxyz quat).
        grain_qpos: (n, 7) every grain's free-joint pose.
        max_speed_m_s: the fastest grain's speed when settling stopped.
        settle_time_s: simulated time it took.
        key: its cache key (pile_key), which names the pile in episode records; "" until settle() returns it.
    """

    bowl_qpos: np.ndarray
    grain_qpos: np.ndarray
    max_speed_m_s: float
    settle_time_s: float
    key: str = ""


_MEMORY: dict[str, SettledPile] = {}
# the driver's piles by key while this process runs a driver's pieces (use_shipped_piles); None: settle as usual
_SHIPPED: dict[str, SettledPile] | None = None


class PileNotShipped(RuntimeError):
    """A worker needed a pile the driver did not hand it (it settles none itself: see the module's docstring)."""


def use_shipped_piles(piles: dict[str, SettledPile] | None) -> None:
    """
    From now on this process takes every pile from ``piles`` (key -> SettledPile, as ScoopGranular.settled_piles
    gives them on the driver) and raises PileNotShipped for any other, instead of reading its own cache or settling;
    None goes back to the cache and settling.
    """
    global _SHIPPED
    _SHIPPED = None if piles is None else dict(piles)


def cache_dir() -> Path:
    """Disk cache of settled piles: $VERAGMIL_CACHE_DIR, else $XDG_CACHE_HOME/veragmil_suite/piles."""
    if os.environ.get("VERAGMIL_CACHE_DIR"):
        return Path(os.environ["VERAGMIL_CACHE_DIR"])
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    return base / "veragmil_suite" / "piles"


def pile_model_xml(bowl: Bowl, pile: GrainPile, option: dict, timestep: float) -> str:
    """The standalone settling model: a table top at z=0, the bowl resting on it, the grains on their lattice."""
    root = ET.Element("mujoco", model="pile")
    opt = ET.SubElement(root, "option", timestep=repr(timestep), **{k: str(v) for k, v in option.items()})
    ET.SubElement(opt, "flag", eulerdamp="disable")  # as in ScoopTask
    world = ET.SubElement(root, "worldbody")
    table = ET.SubElement(
        world, "geom", name="table", type="box", pos="0 0 -0.025", size="0.5 0.5 0.025", friction="0.1 0.005 0.0001"
    )
    for key, value in contact_groups.SUPPORT.items():
        table.set(key, str(value))
    world.append(bowl.get_obj())
    for body in pile.bodies():
        world.append(body)
    return ET.tostring(root, encoding="unicode")


def _key(xml: str) -> str:
    return hashlib.sha256((xml + mujoco.__version__ + SETTLE_VERSION).encode()).hexdigest()[:24]


# each pile's keys by the rest of its settling model: building the model's XML to hash it cost more than the rest
# of a reset's settling (about 45 ms for 300 grains of rice), and a pile's own XML never changes (GrainPile)
_KEYS: weakref.WeakKeyDictionary[GrainPile, dict[tuple, str]] = weakref.WeakKeyDictionary()


def pile_key(bowl: Bowl, pile: GrainPile, option: dict, timestep: float) -> str:
    """The cache key of this bowl and pile: its settling model's XML, the MuJoCo version and SETTLE_VERSION."""
    rest = (
        ET.tostring(bowl.get_obj(), encoding="unicode"),
        tuple((k, str(v)) for k, v in option.items()),
        repr(timestep),
        mujoco.__version__,
        SETTLE_VERSION,
    )
    keys = _KEYS.setdefault(pile, {})
    if rest not in keys:
        keys[rest] = _key(pile_model_xml(bowl, pile, option, timestep))
    return keys[rest]


def settle(bowl: Bowl, pile: GrainPile, option: dict, timestep: float, use_disk: bool = True) -> SettledPile:
    """The settled pile for this bowl and pile: shipped from a driver, from memory, from disk, or simulated now.

    Raises:
        PileNotShipped: [this process runs on shipped piles (use_shipped_piles) and was not handed this one]
    """
    key = pile_key(bowl, pile, option, timestep)
    if _SHIPPED is not None:
        if key not in _SHIPPED:
            raise PileNotShipped(
                f"settled pile {key} ({pile.n_grains} grains of {pile.food.name}) was not handed over by the driver, "
                f"which shipped {len(_SHIPPED)}; a worker settles none itself (piles differ by CPU). Is this "
                f"worker's MuJoCo ({mujoco.__version__}) the driver's?"
            )
        return replace(_SHIPPED[key], key=key)
    if key in _MEMORY:
        return _MEMORY[key]
    path = cache_dir() / f"{key}.npz"
    entry = pile_cache.load(path, pile.n_grains) if use_disk else None  # None: missing or invalid, settled anew
    if entry is not None:
        _MEMORY[key] = SettledPile(*entry, key=key)
        return _MEMORY[key]
    result = replace(simulate_settling(pile_model_xml(bowl, pile, option, timestep), bowl, pile), key=key)
    _MEMORY[key] = result
    if use_disk:
        pile_cache.save(path, result.bowl_qpos, result.grain_qpos, result.max_speed_m_s, result.settle_time_s)
    return result


def simulate_settling(xml: str, bowl: Bowl, pile: GrainPile) -> SettledPile:
    """Runs a pile's settling model (pile_model_xml) until the pile is still; no cache read or written."""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    bowl_joint = model.joint(bowl.joints[0]).qposadr[0]
    grain_adr = np.array([model.joint(name).qposadr[0] for name in pile.joint_names])
    bowl_pos = np.array([0.0, 0.0, -bowl.bottom_offset[2]])
    data.qpos[bowl_joint : bowl_joint + 7] = np.concatenate([bowl_pos, [1.0, 0.0, 0.0, 0.0]])
    lattice = pile.lattice_qpos(bowl.shape, rim_center=bowl_pos + bowl.rim_offset)
    data.qpos[grain_adr[:, None] + np.arange(7)] = lattice
    body_ids = np.array([model.body(name).id for name in pile.body_names])
    steps_per_check = max(1, round(SETTLE_CHECK_EVERY_S / model.opt.timestep))
    rim_radius = min(bowl.shape.rim_semi_axes)
    speed = np.inf
    for _ in range(SETTLE_RETRIES + 1):
        speed = _run_until_still(model, data, body_ids, steps_per_check)
        # a grain that bounced over the rim is dropped again onto the middle of the pile
        rel = data.xpos[body_ids] - data.qpos[bowl_joint : bowl_joint + 3]
        escaped = np.flatnonzero(np.hypot(rel[:, 0], rel[:, 1]) > rim_radius - 0.5 * pile.radii)
        if escaped.size == 0:
            break
        top = data.xpos[body_ids, 2].max()
        for k, i in enumerate(escaped):
            adr = grain_adr[i]
            data.qpos[adr : adr + 3] = [bowl_pos[0], bowl_pos[1], top + (k + 1) * 2.2 * pile.radii.max()]
            data.qvel[model.jnt_dofadr[model.joint(pile.joint_names[i]).id] :][:6] = 0.0
        data.time = 0.0
    bowl_qpos = data.qpos[bowl_joint : bowl_joint + 7].copy()
    grain_qpos = data.qpos[grain_adr[:, None] + np.arange(7)].copy()
    return SettledPile(bowl_qpos, grain_qpos, speed, float(data.time))


def _run_until_still(model: mujoco.MjModel, data: mujoco.MjData, body_ids: np.ndarray, steps_per_check: int) -> float:
    """Steps until every grain has stayed slower than SETTLE_SPEED_M_S, and within SETTLE_DRIFT_M of where it was,
    for SETTLE_HOLD_S (or until SETTLE_MAX_S); returns the fastest grain's speed then."""
    speed = np.inf
    still_since, still_at = None, None
    while data.time < SETTLE_MAX_S:
        mujoco.mj_step(model, data, nstep=steps_per_check)
        # cvel is (angular, linear) at the body's subtree centre of mass: the linear part is the grain's velocity
        speed = float(np.linalg.norm(data.cvel[body_ids, 3:], axis=1).max())
        if not np.isfinite(speed):
            raise RuntimeError("the pile blew up while settling (non-finite velocities)")
        if data.time < SETTLE_MIN_S or speed >= SETTLE_SPEED_M_S:
            still_since = None
            continue
        if still_since is None or np.linalg.norm(data.xpos[body_ids] - still_at, axis=1).max() > SETTLE_DRIFT_M:
            still_since, still_at = data.time, data.xpos[body_ids].copy()
        elif data.time - still_since >= SETTLE_HOLD_S - 1e-9:
            break
    return speed
