// Pinocchio's joint-torque regressor over a chunk of samples, into a caller's buffer.
//
// Built by `python -m sensorless.regressor.native build` (the Makefile does it) and called through
// ctypes, which releases the GIL: the Python loop of one binding call per sample (about 2.2 us on
// a UR5, of which the C++ work is about 1.3 us) becomes one call per chunk, optionally split
// across threads (one pinocchio::Data each). The model is rebuilt here from its kinematic tree
// (joint types, parents, placements, axes): the regressor does not depend on the inertias.
#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/regressor.hpp>

#include <string>
#include <thread>
#include <vector>

using namespace pinocchio;

namespace {
using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Kinematically, an axis-aligned joint (RX, PZ, RUBY, ...) is its unaligned form with a unit axis (the
// Python side maps them; same cost), so seven joint models cover what URDF and MJCF parsers produce.
JointIndex add_joint(Model& m, int type, JointIndex parent, const SE3& M, const Eigen::Vector3d& axis,
                     const std::string& name, bool& ok) {
  switch (type) {
    case 0: return m.addJoint(parent, JointModelRevoluteUnaligned(axis), M, name);
    case 1: return m.addJoint(parent, JointModelRevoluteUnboundedUnaligned(axis), M, name);
    case 2: return m.addJoint(parent, JointModelPrismaticUnaligned(axis), M, name);
    case 3: return m.addJoint(parent, JointModelFreeFlyer(), M, name);
    case 4: return m.addJoint(parent, JointModelSpherical(), M, name);
    case 5: return m.addJoint(parent, JointModelTranslation(), M, name);
    case 6: return m.addJoint(parent, JointModelPlanar(), M, name);
    default: ok = false; return 0;
  }
}
}  // namespace

extern "C" {

// A model from its tree: joint k (1-based in Pinocchio) has type types[k-1] (codes above), parent
// parents[k-1], placement placements[12(k-1) ...] (rotation row-major, then translation) and axis
// axes[3(k-1) ...] (unaligned joints). Returns nullptr for an unknown joint type.
void* slr_model_new(int n_joints, const int* types, const int* parents, const double* placements,
                    const double* axes) {
  Model* m = new Model();
  bool ok = true;
  for (int k = 0; k < n_joints && ok; ++k) {
    const double* P = placements + 12 * k;
    Eigen::Matrix3d R;
    R << P[0], P[1], P[2], P[3], P[4], P[5], P[6], P[7], P[8];
    const SE3 M(R, Eigen::Vector3d(P[9], P[10], P[11]));
    const Eigen::Vector3d axis(axes[3 * k], axes[3 * k + 1], axes[3 * k + 2]);
    const JointIndex id = add_joint(*m, types[k], parents[k], M, axis, "j" + std::to_string(k + 1), ok);
    if (ok) m->appendBodyToJoint(id, Inertia::Identity(), SE3::Identity());
  }
  if (!ok) {
    delete m;
    return nullptr;
  }
  return m;
}

void slr_model_free(void* model) { delete static_cast<Model*>(model); }

int slr_model_nq(void* model) { return static_cast<Model*>(model)->nq; }
int slr_model_nv(void* model) { return static_cast<Model*>(model)->nv; }

// out + i*si + r*sr (10 n_bodies contiguous doubles) = row rows[r] of Y(Q[i], V[i], A[i]) for i < n, r < n_rows;
// Q (n, nq), V and A (n, nv), all C-contiguous. `threads` > 1 splits the samples into contiguous blocks.
int slr_regressor_strided(void* model, int n, const double* Q, const double* V, const double* A, int n_rows,
                          const int* rows, double* out, long si, long sr, int threads) {
  const Model& m = *static_cast<Model*>(model);
  const int nq = m.nq, nv = m.nv, p = 10 * (m.njoints - 1);
  auto work = [&](int lo, int hi) {
    Data d(m);
    for (int i = lo; i < hi; ++i) {
      const Eigen::Map<const Eigen::VectorXd> q(Q + size_t(i) * nq, nq), v(V + size_t(i) * nv, nv),
          a(A + size_t(i) * nv, nv);
      computeJointTorqueRegressor(m, d, q, v, a);
      for (int r = 0; r < n_rows; ++r)
        Eigen::Map<Eigen::RowVectorXd>(out + i * si + r * sr, p) = d.jointTorqueRegressor.row(rows[r]);
    }
  };
  if (threads <= 1 || n < 2 * threads) {
    work(0, n);
    return 0;
  }
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back(work, int(long(n) * t / threads), int(long(n) * (t + 1) / threads));
  for (auto& th : pool) th.join();
  return 0;
}

// out[i] (n_rows x 10 n_bodies, row-major) = rows `rows` of Y(Q[i], V[i], A[i]) for i < n (C-contiguous out).
int slr_regressor(void* model, int n, const double* Q, const double* V, const double* A, int n_rows,
                  const int* rows, double* out, int threads) {
  const int p = 10 * (static_cast<Model*>(model)->njoints - 1);
  return slr_regressor_strided(model, n, Q, V, A, n_rows, rows, out, long(n_rows) * p, p, threads);
}
}
