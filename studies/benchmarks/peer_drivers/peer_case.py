"""What both peer drivers share: reading the case a `sensorless benchmark peers` run wrote, and
writing a driver's result. Run from the peer's own venv (NumPy and Pinocchio only, no sensorless)."""

import json
import os

import numpy as np
import pinocchio as pin


def load_case(case_path):
    """The case (``urdf``, ``body_names``, training ``q``, ``v``, ``a``, ``tau``, …), the model, its body
    names and joint ids, and Pinocchio's joint-torque regressor stacked over the samples (n·nv rows)."""
    c = np.load(case_path)
    model = pin.buildModelFromUrdf(str(c["urdf"]))
    data = model.createData()
    bodies = [str(b) for b in c["body_names"]]
    jids = [model.getJointId(b) for b in bodies]
    q, v, a = c["q"], c["v"], c["a"]
    n, nv = q.shape[0], model.nv
    Y = np.empty((n * nv, 10 * (model.njoints - 1)))
    for k in range(n):
        Y[k * nv:(k + 1) * nv] = pin.computeJointTorqueRegressor(model, data, q[k], v[k], a[k])
    return c, model, bodies, jids, Y


def write_result(out_path, params, info: dict) -> None:
    """OUT: ``params`` (10 per body, Pinocchio order) and ``info`` (JSON), written atomically."""
    tmp = out_path + ".tmp.npz"
    np.savez(tmp, params=np.asarray(params, dtype=float), info=json.dumps(info))
    os.replace(tmp, out_path)
