"""A record of another machine: a guided drop weight onto a specimen, the load cell and the accelerometer in the
striker, 100 kHz, with the ringing of a real striker (an independent little simulator, not the package's model).

The striker (mass M, falling at V0) strikes a specimen on a rigid anvil whose force is nonlinear and hysteretic:
k·δ^1.5 while it is compressed, and on unloading the same curve scaled down to a permanent set (a crushed
specimen); the striker then rebounds and flies clear for the rest of the record. The load cell reads the contact
force plus the striker's structural ringing (a sine that grows with the force taken and dies away after the
contact) and, after the main pulse, a small ringing blip (the guide rails); the accelerometer reads the
striker's kinematic acceleration, gravity removed, positive down (it is braked: negative), with ringing of its
own. White noise on both.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from impactometer.recording import Recording

GRAVITY = 9.80665


def specimen_force(depth: float, deepest: float, stiffness: float, set_fraction: float) -> float:
    """Contact force [N] of the specimen at ``depth`` [m] below its free surface, having been compressed to
    ``deepest`` [m]: k·δ^1.5 on loading, the loading curve at the deepest point scaled down to a permanent set of
    ``set_fraction``·deepest on unloading."""
    if depth <= 0.0:
        return 0.0
    if depth >= deepest:
        return stiffness * depth ** 1.5
    permanent = set_fraction * deepest
    if depth <= permanent:
        return 0.0
    return stiffness * deepest ** 1.5 * ((depth - permanent) / (deepest - permanent)) ** 2


def drop_weight(mass: float = 20.0, velocity: float = 3.0, *, stiffness: float = 4e7, set_fraction: float = 0.7,
                sample_rate: float = 100e3, duration: float = 0.18, pre_trigger: float = 0.02, noise: float = 0.004,
                ringing: float = 0.03, blip: float = 20.0, seed: int = 0) -> Recording:
    """The record: ``contact_force`` [N] and ``piston_acceleration`` [m/s²] (the striker's: down positive), with
    truth metadata. ``noise`` and ``ringing`` are fractions of the peak force (peak acceleration); ``blip`` the
    amplitude [N] of the ringing after the main pulse."""
    state = {"deepest": 0.0}

    def rhs(t, y):
        depth, speed = y
        state["deepest"] = max(state["deepest"], depth)
        force = specimen_force(depth, state["deepest"], stiffness, set_fraction)
        return [speed, GRAVITY - force / mass]

    def parted(t, y):
        return y[0] - set_fraction * state["deepest"] if t > 1e-4 else 1.0
    parted.terminal = True
    parted.direction = -1
    fine = 20 * sample_rate
    contact = solve_ivp(rhs, (0.0, duration), [0.0, velocity], max_step=1.0 / fine, events=parted, rtol=1e-9,
                        atol=1e-12, dense_output=True)
    t_end = float(contact.t[-1])
    time = np.arange(-pre_trigger, duration - pre_trigger, 1.0 / sample_rate)
    inside = (time >= 0.0) & (time <= t_end)
    depth = np.zeros_like(time)
    depth[inside] = contact.sol(time[inside])[0]
    deepest = np.maximum.accumulate(np.where(inside, depth, 0.0))
    force = np.array([specimen_force(d, m, stiffness, set_fraction) if ok else 0.0
                      for d, m, ok in zip(depth, deepest, inside, strict=True)])
    acceleration = -force / mass  # kinematic, gravity removed, down positive: braked by the contact
    rng = np.random.default_rng(seed)
    peak_force, peak_acceleration = float(force.max()), float(np.abs(acceleration).max())
    after = np.clip(time, 0.0, None)
    # the striker's ringing grows with the force it takes and dies away once the contact has ended
    envelope = np.maximum.accumulate(force) * np.exp(-np.clip(time - t_end, 0.0, None) / 3e-3)
    ring = envelope / max(peak_force, 1e-300) * np.sin(2 * np.pi * 1.7e3 * after)
    late = time - (t_end + 0.01)
    blip_wave = np.where(late >= 0.0, np.exp(-np.clip(late, 0.0, None) / 2e-3) * np.sin(2 * np.pi * 900.0 * late),
                         0.0)
    force_read = (force + ringing * peak_force * ring + blip * blip_wave
                  + noise * peak_force * rng.standard_normal(time.size))
    ring_a = envelope / max(peak_force, 1e-300) * np.sin(2 * np.pi * 5.3e3 * after + 0.4)
    acceleration_read = (acceleration + ringing * peak_acceleration * ring_a
                         + noise * peak_acceleration * rng.standard_normal(time.size))
    metadata = {"mass_kg": mass, "velocity_m_s": velocity, "machine": "guided drop weight"}
    return Recording(sample_rate=sample_rate, start_time=float(time[0]),
                     channels={"contact_force": force_read, "piston_acceleration": acceleration_read},
                     metadata=metadata)
