"""--lowpass reaches every measured channel (issue 27, item 2): joints, motor currents, the base pose,
twist and acceleration, the IMU and the contact wrenches get the same zero-phase Butterworth at the
same cut-off, recorded in the provenance; a twist derived from the pose is filtered at that cut-off too."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sensorless.data import Trajectory, prepare
from sensorless.data.filtering import lowpass_channels

RATE, SLOW, FAST = 200.0, 1.0, 40.0  # Hz: sampling, the motion, the noise (cut-off 10 Hz)


def _fit(x, t, f):
    """(sin, cos) coefficients of the f-Hz component of each column of x (least squares)."""
    A = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])
    return np.linalg.lstsq(A, x.reshape(len(t), -1), rcond=None)[0]


@pytest.fixture(scope="module")
def noisy():
    """Every channel = a 1 Hz motion (random amplitude and phase per column) + a 40 Hz disturbance."""
    rng = np.random.default_rng(0)
    t = np.arange(0, 4.0, 1 / RATE)
    n = len(t)

    def channel(*shape):
        k = int(np.prod(shape))
        amp, ph = rng.uniform(0.5, 2.0, k), rng.uniform(0, 2 * np.pi, k)
        return (amp * np.sin(2 * np.pi * SLOW * t[:, None] + ph)
                + 0.3 * amp * np.sin(2 * np.pi * FAST * t[:, None] + ph)).reshape(n, *shape)

    yaw = 0.5 * np.sin(2 * np.pi * SLOW * t) + 0.05 * np.sin(2 * np.pi * FAST * t)
    quat = Rotation.from_euler("z", yaw[:, None]).as_quat()
    quat[::3] *= -1  # a tracker's sign flips: same rotations
    base_q = np.hstack([channel(3), quat])
    extras = {"imu_acc": channel(3), "imu_gyro": channel(3), "contact_forces": channel(2, 6), "current": channel(2),
              "contact": np.ones((n, 2), bool)}
    traj = Trajectory(t=t, q=channel(2), v=channel(2), a=channel(2), tau=channel(2), joint_names=("a", "b"),
                      base_q=base_q, base_v=channel(6), base_a=channel(6), extras=extras)
    return traj, yaw


def test_every_measured_channel_is_low_passed_without_phase(noisy):
    traj, yaw = noisy
    out = prepare(traj, lowpass=10.0, resample="off", rest="off", base_velocity="logged")
    channels = lowpass_channels(traj)
    assert set(channels) == {"q", "v", "a", "tau", "base_q", "base_v", "base_a", "imu_acc", "imu_gyro",
                             "contact_forces", "current"}
    assert out.provenance["lowpass"]["channels"] == channels and out.provenance["lowpass"]["cutoff_hz"] == 10.0
    inner = slice(100, -100)
    t = traj.t[inner]
    for name in channels:
        if name == "base_q":
            continue
        raw = traj.extras[name] if name in traj.extras else getattr(traj, name)
        got = out.extras[name] if name in out.extras else getattr(out, name)
        slow_in, slow_out = _fit(raw[inner], t, SLOW), _fit(got[inner], t, SLOW)
        fast_in, fast_out = _fit(raw[inner], t, FAST), _fit(got[inner], t, FAST)
        # the 40 Hz part loses > 40 dB, the 1 Hz part keeps its amplitude and phase (zero-phase filter)
        assert np.all(np.hypot(*fast_out) < 0.01 * np.hypot(*fast_in)), name
        np.testing.assert_allclose(slow_out, slow_in, atol=2e-3 * np.abs(slow_in).max(), err_msg=name)
    np.testing.assert_array_equal(out.extras["contact"], traj.extras["contact"])  # flags are not signals
    # the base pose: position filtered like the rest; the orientation keeps unit quaternions and its
    # 1 Hz yaw, loses the 40 Hz wobble, whatever the logged sign
    np.testing.assert_allclose(np.linalg.norm(out.base_q[:, 3:], axis=1), 1.0, atol=1e-12)
    got_yaw = Rotation.from_quat(out.base_q[:, 3:]).as_euler("xyz")[:, 2]
    assert abs(_fit(got_yaw[inner], t, FAST)).max() < 5e-4
    np.testing.assert_allclose(_fit(got_yaw[inner], t, SLOW), _fit(yaw[inner], t, SLOW), atol=1e-3)
    # without --lowpass nothing is filtered (the test can fail)
    same = prepare(traj, resample="off", rest="off", base_velocity="logged")
    np.testing.assert_array_equal(same.extras["imu_acc"], traj.extras["imu_acc"])
    assert "lowpass" not in same.provenance


def test_a_twist_from_the_pose_is_filtered_at_the_same_cut_off(noisy):
    """Tracker noise on the pose: the derived base twist above the cut-off loses most of its power
    with --lowpass 5, its slow part stays."""
    traj, _ = noisy
    rng = np.random.default_rng(1)
    t = traj.t
    pos = np.column_stack([0.2 * np.sin(2 * np.pi * SLOW * t), 0.1 * np.cos(2 * np.pi * SLOW * t), 0 * t])
    pose = np.hstack([pos + 5e-4 * rng.standard_normal(pos.shape), np.tile([0, 0, 0, 1.0], (len(t), 1))])
    log = traj.with_(base_q=pose, base_v=None, base_a=None, extras={})
    raw = prepare(log, resample="off", rest="off")
    low = prepare(log, lowpass=5.0, resample="off", rest="off")
    assert low.provenance["lowpass"]["channels"][-3:] == ["base_q", "base_v", "base_a"]
    assert "low-pass 5 Hz" in low.provenance["base_v"] and "low-pass off" in raw.provenance["base_v"]

    def power_above(x, f0=8.0):
        x = x[100:-100] - x[100:-100].mean(axis=0)
        return float(np.sum(np.abs(np.fft.rfft(x, axis=0)[np.fft.rfftfreq(len(x), 1 / RATE) > f0]) ** 2))

    assert power_above(low.base_v[:, :3]) < 0.1 * power_above(raw.base_v[:, :3])
    assert power_above(low.base_a[:, :3]) < 0.1 * power_above(raw.base_a[:, :3])
    truth_v = np.column_stack([0.4 * np.pi * np.cos(2 * np.pi * SLOW * t), -0.2 * np.pi * np.sin(2 * np.pi * SLOW * t)])
    inner = slice(100, -100)
    assert np.abs(low.base_v[inner, :2] - truth_v[inner]).max() < 0.02 * np.abs(truth_v).max()
