"""Synthetic quadruped walks over changing terrain (``walk_files`` writes them as ROS 2 MCAP).

Each walk is a trot whose terrain changes in patches of varied length. Terrains differ in ways a sequence model can
learn but no single threshold separates: how sharply a foot's force rises at touchdown, the stance force profile
(soft ground loads slowly), slip (tangential force noise and bursts), the vibration spectrum the body picks up, and
body sway. Every patch draws its parameters around its terrain's values, and speed and gait frequency vary, so the
classes overlap. Every walk is a run of its own (:mod:`.run_conditions`): its speed, gait, sensor gains and IMU
mounting differ from the other walks'. Ground truth goes to ``<log>.truth.json`` beside each log, for evaluation only.

The signals are the IMU at 100 Hz and the four feet's wrenches at 50 Hz.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .run_conditions import RunConditions

TERRAINS = ("concrete", "grass", "gravel", "mulch", "dirt", "sand")
FEET = ("fl", "fr", "rl", "rr")
IMU_HZ = 100.0
FOOT_HZ = 50.0
MASS_KG = 12.0
G = 9.81
PATCH_SPREAD = 0.08  # lognormal spread of a patch's parameters around its terrain's: how much terrains overlap


@dataclass(frozen=True)
class TerrainParams:
    """Typical physics of one terrain; each patch draws around these."""

    rise_s: float  # time constant of the force rise at touchdown: small = sharp impact
    impact: float  # touchdown spike, as a fraction of the foot's load
    sink: float  # 0 = symmetric stance profile, larger = loads slowly (soft ground)
    slip: float  # tangential force noise, fraction of load
    vib_hz: float  # resonance of the vibration the body picks up
    vib: float  # vibration amplitude, m/s²
    sway: float  # body roll/pitch amplitude, rad


TERRAIN_PARAMS: dict[str, TerrainParams] = {
    "concrete": TerrainParams(0.008, 0.50, 0.00, 0.02, 34.0, 0.80, 0.015),
    "grass": TerrainParams(0.030, 0.20, 0.25, 0.05, 14.0, 0.25, 0.030),
    "gravel": TerrainParams(0.012, 0.35, 0.10, 0.14, 24.0, 1.40, 0.050),
    "mulch": TerrainParams(0.045, 0.10, 0.40, 0.09, 8.0, 0.15, 0.045),
    "dirt": TerrainParams(0.020, 0.28, 0.15, 0.035, 19.0, 0.45, 0.025),
    "sand": TerrainParams(0.060, 0.04, 0.60, 0.18, 5.0, 0.10, 0.065),
}


@dataclass(frozen=True)
class Walk:
    """One generated walk, sampled at ``IMU_HZ`` (feet are decimated to ``FOOT_HZ`` when written)."""

    t0: float  # absolute start time (s)
    times: np.ndarray  # (T,) seconds since t0
    forces: np.ndarray  # (T, 4, 3) N, feet in FEET order
    gyro: np.ndarray  # (T, 3) rad/s
    accel: np.ndarray  # (T, 3) m/s²
    quat: np.ndarray  # (T, 4) x, y, z, w
    truth: tuple[tuple[float, float, str], ...]  # (start_s, stop_s, terrain) relative to t0
    distance: np.ndarray  # (T,) m walked since t0 (the demo camera's ground moves with it)


def _smooth(x: np.ndarray, n: int) -> np.ndarray:
    """Moving average over ``n`` samples along axis 0 (edges padded), to blend patch boundaries."""
    if n <= 1:
        return x
    k = np.ones(n) / n
    pad = np.pad(x, (n // 2, n - 1 - n // 2), mode="edge")
    return np.convolve(pad, k, mode="valid")


def _slow_noise(rng: np.random.Generator, n: int, fs: float, cutoff_hz: float) -> np.ndarray:
    """Unit-variance noise with no content above ``cutoff_hz``."""
    spec = np.fft.rfft(rng.standard_normal(n))
    spec[0] = 0  # zero mean; and a walk shorter than 1 / cutoff keeps its slowest wave, not only a constant
    spec[np.fft.rfftfreq(n, 1 / fs) > max(cutoff_hz, 1.5 * fs / n)] = 0
    x = np.fft.irfft(spec, n)
    return x / (x.std() + 1e-12)


def _resonant(rng: np.random.Generator, n: int, fs: float, f0: float, q: float) -> np.ndarray:
    """Unit-variance noise shaped by a resonance at ``f0`` Hz with quality ``q``."""
    f = np.fft.rfftfreq(n, 1 / fs)
    h = 1.0 / (1.0 - (f / f0) ** 2 + 1j * f / (q * f0))
    x = np.fft.irfft(np.fft.rfft(rng.standard_normal(n)) * h, n)
    return x / (x.std() + 1e-12)


def _patches(rng: np.random.Generator, duration_s: float, order: list[str]) -> list[tuple[float, float, str]]:
    """Terrain patches of varied length (5 to 60 s, a few long ones) covering the walk."""
    out, t, i = [], 0.0, 0
    while t < duration_s:
        length = float(rng.choice([rng.uniform(5, 20), rng.uniform(15, 60)], p=[0.6, 0.4]))
        terrain = order[i] if i < len(order) else str(rng.choice(TERRAINS))
        if out and terrain == out[-1][2]:
            terrain = TERRAINS[(TERRAINS.index(terrain) + 1 + int(rng.integers(5))) % len(TERRAINS)]
        out.append((t, min(duration_s, t + length), terrain))
        t += length
        i += 1
    return out


def generate_walk(seed: int, duration_s: float, *, t0: float = 1.7e9, conditions: RunConditions | None = None) -> Walk:
    """Simulate one walk of ``duration_s`` seconds (deterministic for a seed).

    Args:
        seed: The walk: its terrain patches and, unless ``conditions`` is given, its run conditions.
        duration_s: Length of the walk.
        t0: Absolute time of its first sample.
        conditions: Speed, gait, sensor gains and IMU mounting (default: drawn for the seed, so every walk is a
            run of its own; ``RunConditions()`` is the nominal robot).
    """
    run = RunConditions.draw(seed) if conditions is None else conditions
    rng = np.random.default_rng(seed)
    fs = IMU_HZ
    n = int(duration_s * fs)
    t = np.arange(n) / fs
    order = list(rng.permutation(TERRAINS))  # every class early in every walk
    truth = _patches(rng, duration_s, order)

    # Per-sample terrain parameters, each patch drawn around its terrain's values (lognormal spread: overlap).
    fields = TerrainParams.__dataclass_fields__
    par = {k: np.empty(n) for k in fields}
    patch_of = np.empty(n, dtype=np.int64)
    for p, (a, b, terrain) in enumerate(truth):
        sl = slice(int(a * fs), int(b * fs))
        patch_of[sl] = p
        base = TERRAIN_PARAMS[terrain]
        for k in fields:
            par[k][sl] = getattr(base, k) * float(np.exp(rng.normal(0, PATCH_SPREAD)))
    blend = int(0.4 * fs)  # terrain transitions take a stride or so
    par = {k: _smooth(v, blend) for k, v in par.items()}

    speed = run.speed * np.clip(0.7 + 0.3 * _slow_noise(rng, n, fs, 0.02), 0.25, 1.3)  # m/s
    freq = run.gait * (1.3 + 0.9 * speed + 0.08 * _slow_noise(rng, n, fs, 0.05))  # gait cycles / s
    phase = np.cumsum(freq) / fs
    duty = np.clip(0.62 - 0.12 * speed + 0.12 * par["sink"], 0.4, 0.8)
    stance_s = duty / freq

    load = MASS_KG * G / 2 * (1 + 0.25 * (speed - 0.7))  # two feet carry the body in a trot
    forces = np.zeros((n, 4, 3))
    touchdown = np.zeros(n)
    for j, offset in enumerate((0.0, 0.5, 0.5, 0.0)):  # fl, fr, rl, rr: diagonal pairs in phase
        p = np.mod(phase + offset + 0.01 * j, 1.0)
        s = p / duty  # progress through stance, < 1 while on the ground
        on = s < 1.0
        s = np.where(on, s, 0.0)
        t_in = s * stance_s  # seconds since touchdown
        rise = 1.0 - np.exp(-t_in / par["rise_s"])
        shape = np.sin(np.pi * s) ** (0.5 + par["sink"]) * (1 + par["sink"] * (s - 0.5))
        spike = par["impact"] * np.exp(-t_in / (0.6 * par["rise_s"]))
        fz = load * (1.6 * rise * shape + spike)
        slip = par["slip"] * load * _resonant(rng, n, fs, 9.0, 1.5)
        bursts = (rng.random(n) < par["slip"] * 0.02) * rng.normal(0, 3, n) * load * par["slip"]
        fx = -0.18 * load * (0.6 + speed) * np.sin(2 * np.pi * s) + slip + _smooth(bursts, 6)
        fy = (0.06 if j % 2 == 0 else -0.06) * load * np.sin(np.pi * s) + 0.5 * slip[::-1]
        forces[:, j, 0] = np.where(on, fx, 0.0)
        forces[:, j, 1] = np.where(on, fy, 0.0)
        forces[:, j, 2] = np.where(on, fz, 0.0)
        touchdown += np.r_[0, np.diff(on.astype(float)) > 0]
    # Over a stride the feet carry the body's weight: scale the normal forces so the mean is m·g.
    forces[:, :, 2] *= MASS_KG * G / forces[:, :, 2].sum(axis=1).mean()
    forces += rng.normal(0, 0.4, forces.shape)  # sensor noise, N

    # Vibration: the ground's resonance excited by walking (per patch) and ringing after each touchdown.
    vib = np.zeros((n, 3))
    for p in range(len(truth)):
        idx = np.flatnonzero(patch_of == p)
        if idx.size < 8:
            continue
        f0 = float(np.median(par["vib_hz"][idx]))
        for ax in range(3):
            vib[idx, ax] = _resonant(rng, idx.size, fs, min(f0, 0.45 * fs), 3.0)
    k = np.arange(int(0.25 * fs)) / fs
    ring = np.exp(-k * 25.0) * np.sin(2 * np.pi * 20.0 * k)
    vib[:, 2] += 2.0 * np.convolve(touchdown * par["impact"], ring)[:n]
    vib *= (par["vib"] * (0.5 + speed))[:, None]

    total = forces.sum(axis=1)  # (T, 3)
    dv = np.gradient(speed, 1 / fs)
    accel = (
        np.stack([dv + (total[:, 0]) / MASS_KG, total[:, 1] / MASS_KG, total[:, 2] / MASS_KG], axis=1)
        + vib
        + rng.normal(0, 0.05, (n, 3))
    )

    sway = par["sway"]
    roll = sway * np.sin(2 * np.pi * phase + 0.3) + 0.2 * sway * _slow_noise(rng, n, fs, 2.0)
    pitch = 0.6 * sway * np.sin(4 * np.pi * phase) + 0.02 * _slow_noise(rng, n, fs, 0.05)
    yaw = np.cumsum(0.15 * _slow_noise(rng, n, fs, 0.03) + 3 * par["slip"] * _slow_noise(rng, n, fs, 3.0)) / fs
    gyro = np.stack([np.gradient(a, 1 / fs) for a in (roll, pitch, yaw)], axis=1) + rng.normal(0, 0.01, (n, 3))
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    quat = np.stack(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ],
        axis=1,
    )
    accel, gyro, quat = run.measure_imu(accel, gyro, quat)
    return Walk(t0, t, run.measure_forces(forces), gyro, accel, quat, tuple(truth), np.cumsum(speed) / fs)
