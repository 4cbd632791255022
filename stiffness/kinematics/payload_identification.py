"""Payload identification from static poses (offline science; behind `stiffcomp payload`).

For poses k with sensor orientation R_k and static readings W_k, with g_k = R_k^T g,

    F_k = m g_k + b_F,    T_k = -[g_k]x (m c) + b_T

is linear in (m, m c, b_F, b_T); `identify_payload` solves it by least squares. The result feeds
the ``gravity`` section that `service.gravity.GravityCompensator` applies every cycle.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stiffness.errors import DataError
from stiffness.kinematics.spatial import skew

COLUMNS = [f"q{i}_deg" for i in range(1, 7)] + ["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]


def read_poses(path: str) -> np.ndarray:
    p = Path(path)
    if not p.exists():
        raise DataError(f"{path}: poses file not found")
    with open(p, newline="") as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise DataError(f"{path}: line 1: missing column(s) {', '.join(missing)}")
        rows = []
        for line, row in enumerate(reader, start=2):
            try:
                vals = [float(row[c]) for c in COLUMNS]
            except (TypeError, ValueError):
                raise DataError(f"{path}: line {line}: every value must be a number") from None
            if not np.all(np.isfinite(vals)):
                raise DataError(f"{path}: line {line}: values must be finite")
            rows.append(vals)
    if len(rows) < 3:
        raise DataError(f"{path}: {len(rows)} pose(s); at least 3 are needed (better 6 or more)")
    return np.array(rows)


@dataclass
class PayloadFit:
    """Result of `identify_payload`; ``ok`` is False when the poses do not determine the payload."""

    mass_kg: float
    cog_m: np.ndarray
    bias: np.ndarray
    residual_rms: np.ndarray      # (6,) per channel
    rank: int
    ok: bool
    message: str


def identify_payload(R_sensor: np.ndarray, wrench: np.ndarray, g: np.ndarray | None = None) -> PayloadFit:
    """Least-squares mass, centre of gravity and bias from static readings.

    Parameters
    ----------
    R_sensor : (K, 3, 3) sensor orientations in the base
    wrench : (K, 6) static readings (no external load), N and Nm
    g : (3,) gravity in base axes, m/s^2 (default [0, 0, -9.81])

    The poses must turn the sensor so that gravity points along at least three independent
    directions in the sensor frame; otherwise ``ok`` is False and the message says so.
    """
    g = np.array([0.0, 0.0, -9.81]) if g is None else np.asarray(g, dtype=float)
    K = len(wrench)
    A = np.zeros((6 * K, 10))
    for k in range(K):
        gk = R_sensor[k].T @ g
        A[6 * k:6 * k + 3, 0] = gk
        A[6 * k:6 * k + 3, 4:7] = np.eye(3)
        A[6 * k + 3:6 * k + 6, 1:4] = -skew(gk)
        A[6 * k + 3:6 * k + 6, 7:10] = np.eye(3)
    y = np.asarray(wrench, dtype=float).reshape(-1)
    x, _, rank, _ = np.linalg.lstsq(A, y, rcond=None)
    res = (y - A @ x).reshape(K, 6)
    rms = np.sqrt((res ** 2).mean(0))
    m = float(x[0])
    cog = x[1:4] / m if abs(m) > 1e-9 else np.zeros(3)
    ok = rank == 10
    msg = "ok" if ok else (f"the {K} poses determine only {rank} of 10 parameters: turn the sensor so that "
                           "gravity points along three independent directions")
    return PayloadFit(m, cog, x[4:10], rms, int(rank), ok, msg)
