"""Gravity compensation and payload identification: round trips and recovery of known parameters."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from service.config import load_config
from service.gravity import GravityCompensator
from stiffness.kinematics.payload_identification import identify_payload

G = np.array([0.0, 0.0, -9.81])


def test_compensation_returns_the_external_wrench_in_any_orientation():
    gc = GravityCompensator(12.0, [0.01, -0.02, 0.11], [3, -2, 5, 0.1, -0.05, 0.02], G)
    rng = np.random.default_rng(0)
    for R in Rotation.random(20, random_state=1).as_matrix():
        ext = rng.normal(size=6) * 100
        reading = ext + np.array(gc.payload_wrench(R)) + gc.bias
        np.testing.assert_allclose(gc.compensate(reading, R), ext, atol=1e-9)


def test_payload_weight_magnitude_is_m_g():
    gc = GravityCompensator(5.0, [0, 0, 0.1], np.zeros(6), G)
    for R in Rotation.random(5, random_state=2).as_matrix():
        assert np.isclose(np.linalg.norm(gc.payload_wrench(R)[:3]), 5.0 * 9.81)


def test_tare_zeroes_the_current_load():
    gc = GravityCompensator(2.0, [0, 0, 0.05], np.zeros(6), G)
    R = Rotation.from_euler("xyz", [0.3, -0.2, 1.0]).as_matrix()
    reading = [10.0, 20.0, 30.0, 1.0, 2.0, 3.0]
    gc.tare(reading, R)
    np.testing.assert_allclose(gc.compensate(reading, R), 0.0, atol=1e-12)


def test_bodies_combine_into_mass_and_centre_of_gravity(tmp_path):
    cfg = load_config()
    sec = cfg.gravity.model_copy(deep=True)
    sec.sensor.mass_kg, sec.sensor.cog_mm = 1.0, [0.0, 0.0, 20.0]
    sec.tool.mass_kg, sec.tool.cog_mm = 3.0, [0.0, 0.0, 100.0]
    sec.fixture.mass_kg, sec.workpiece.mass_kg = 0.0, 0.0
    gc = GravityCompensator.from_config(sec)
    assert gc.mass == 4.0
    np.testing.assert_allclose(gc.cog, [0, 0, 0.080])


def test_identify_payload_recovers_known_parameters():
    m, c, b = 7.5, np.array([0.02, -0.01, 0.09]), np.array([4.0, -3.0, 2.0, 0.2, -0.1, 0.05])
    gc = GravityCompensator(m, c, b, G)
    Rs = Rotation.random(12, random_state=4).as_matrix()
    rng = np.random.default_rng(5)
    W = np.array([np.array(gc.payload_wrench(R)) + b + rng.normal(0, 0.01, 6) for R in Rs])
    fit = identify_payload(Rs, W, G)
    assert fit.ok
    assert abs(fit.mass_kg - m) < 0.01
    np.testing.assert_allclose(fit.cog_m, c, atol=1e-3)
    np.testing.assert_allclose(fit.bias, b, atol=0.05)


def test_identify_payload_says_when_poses_are_degenerate():
    Rs = np.array([np.eye(3)] * 5)                   # gravity along one sensor direction only
    W = np.zeros((5, 6))
    fit = identify_payload(Rs, W, G)
    assert not fit.ok and "three independent directions" in fit.message
