// One sample of the generalised-momentum observer and the collision check, compiled.
//
// The same numbers as MomentumObserver.step (sensorless/estimation/momentum.py), per sample:
//   state      q, v (Pinocchio) from the logged joints (continuous joints as cos/sin, floating base),
//              or for a transmission q = Gq θ + q0, v = G θ̇;
//   dynamics   M = crba(q) (+ Gᵀ M G + M_drive), p = M v, β = Cᵀ v − g − τ_f
//              (computeCoriolisMatrix, computeGeneralizedGravity; τ_f the identified joint or
//              drive terms and the presliding state);
//   observer   r = (b_p/a)[p − p(0)] − (b_u/a)[τ + β], direct form II transposed (scipy's lfilter);
//   monitor    τ_ext = −r[rows], contact ⇔ ∃ j: |τ_ext,j − b_j| > thr_j (after the warm-up).
// The model is the kernel's tree (slr_model_new, native_kernel.cpp) with the identified inertias,
// armature and gravity. Called through ctypes (sensorless/estimation/native_observer.py).
#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include <chrono>
#include <cmath>
#include <vector>

using namespace pinocchio;

extern "C" void* slr_model_new(int n_joints, const int* types, const int* parents, const double* placements,
                               const double* axes);

namespace {
using Vec = Eigen::VectorXd;
using Mat = Eigen::MatrixXd;
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct JointFriction {  // fv v + fc T + st S + off (the joint terms at zero acceleration)
  int iv;
  double eps, rest, vs;
  int product;
  double fv, fc, st, off;
};
struct Presliding {  // fc s_c, s_c the Dahl state on the played position
  int iq, iv;
  double fc, k, play;
  double p = 0.0, s = 0.0;
};
struct Drive {  // g (fv ṡ + fc T(ṡ) + off + k s − k_rest), s = gᵀθ + s0
  Vec g;
  double fv, fc, off, k, krest, eps, s0;
};

inline double sgn(double x) { return double((x > 0) - (x < 0)); }

struct Observer {
  Model* model;
  Data* data;
  int n, mode = 0;  // observer coordinates; mode 0: joints (fixed or floating base), 1: transmission
  // inputs of mode 0
  int nj = 0, na = 0, floating = 0;
  std::vector<int> jq, jv, jcont, act;
  // transmission
  Mat Gq, Gv, Md, Mc;
  Vec q0, wt;
  std::vector<JointFriction> jf;
  std::vector<Presliding> ps;
  std::vector<Drive> drives;
  // filter
  int k = 0;
  double bp[3] = {0, 0, 0}, bu[3] = {0, 0, 0}, a[3] = {1, 0, 0};
  Mat zp, zu;
  Vec p0;
  bool started = false;
  // monitor
  std::vector<int> rows;
  Vec bias, thr;
  long warm = 0, count = 0;
  // work
  Vec qf, vf, tf, p, beta, xu, r, te;
  Mat M;
  const double* in = nullptr;  // bound buffers: [q, v, tau, base_q (7), base_v (6)] and [r, tau_ext]
  double* out = nullptr;

  Observer(Model* m, int n_) : model(m), data(new Data(*m)), n(n_) {
    qf = Vec::Zero(m->nq);
    vf = Vec::Zero(m->nv);
    tf = Vec::Zero(n);
    p = beta = xu = r = Vec::Zero(n);
    M = Mat::Zero(n, n);
  }
  ~Observer() {
    delete data;
    delete model;
  }

  int in_size() const { return mode == 0 ? 2 * nj + na + 13 : 3 * n + 13; }

  void state(const double* q, const double* v, const double* tau, const double* bq, const double* bv) {
    if (mode == 0) {
      if (floating) {
        for (int i = 0; i < 7; ++i) qf[i] = bq ? bq[i] : (i == 6 ? 1.0 : 0.0);
        for (int i = 0; i < 6; ++i) vf[i] = bv ? bv[i] : 0.0;
      }
      for (int j = 0; j < nj; ++j) {
        if (jcont[j]) {
          qf[jq[j]] = std::cos(q[j]);
          qf[jq[j] + 1] = std::sin(q[j]);
        } else {
          qf[jq[j]] = q[j];
        }
        vf[jv[j]] = v[j];
      }
      tf.setZero();
      for (int i = 0; i < na; ++i) tf[act[i]] = tau[i];
    } else {
      const Eigen::Map<const Vec> th(q, n), dth(v, n);
      qf.noalias() = Gq * th;
      qf += q0;
      vf.noalias() = Gv * dth;
      for (int i = 0; i < n; ++i) tf[i] = tau[i];
    }
  }

  // p and β at the current (qf, vf), θ/θ̇ the inputs of a transmission
  void dynamics(const double* q, const double* v) {
    const Model& m = *model;
    Data& d = *data;
    crba(m, d, qf);
    d.M.triangularView<Eigen::StrictlyLower>() = d.M.transpose();
    if (mode == 0) {
      p.noalias() = d.M * vf;
      computeCoriolisMatrix(m, d, qf, vf);
      beta.noalias() = d.C.transpose() * vf;
      computeGeneralizedGravity(m, d, qf);
      beta -= d.g;
      for (const auto& f : jf) {
        const double x = vf[f.iv];
        const bool moving = std::fabs(x) > f.rest;
        const double T = moving ? (f.eps > 0 ? std::tanh(x / f.eps) : sgn(x)) : 0.0;
        const double S = moving ? sgn(x) : 0.0;
        const double e = (x / f.vs) * (x / f.vs);
        const double st = f.product ? std::exp(-e) * T : T - (-std::expm1(-e)) * S;
        beta[f.iv] -= f.fv * x + f.fc * T + f.st * st + f.off;
      }
      presliding();
    } else {
      const Eigen::Map<const Vec> th(q, n), dth(v, n);
      Mc.noalias() = d.M * Gv;
      M.noalias() = Gv.transpose() * Mc;
      M += Md;
      p.noalias() = M * dth;
      computeCoriolisMatrix(m, d, qf, vf);
      Vec& w = wt;
      w.noalias() = d.C.transpose() * vf;
      computeGeneralizedGravity(m, d, qf);
      w -= d.g;
      beta.noalias() = Gv.transpose() * w;
      for (const auto& dr : drives) {
        const double sd = dr.g.dot(dth);
        const double T = dr.eps <= 0 ? sgn(sd) : std::tanh(sd / dr.eps);
        const double s = dr.g.dot(th) + dr.s0;
        const double f = dr.fv * sd + dr.fc * T + dr.off + dr.k * s - dr.krest;
        beta -= f * dr.g;
      }
    }
  }

  void presliding() {
    for (auto& s : ps) {
      const double q = qf[s.iq];
      if (!started) {
        s.p = q;
      } else {
        const double pn = std::min(std::max(s.p, q - s.play), q + s.play);
        const double dq = pn - s.p;
        s.p = pn;
        if (dq != 0) {
          const double u = std::copysign(1.0, dq);
          s.s = u + (s.s - u) * std::exp(-s.k * std::fabs(dq));
        }
      }
      beta[s.iv] -= s.s * s.fc;
    }
  }

  // the filter step on p, τ + β → r; the monitor → flag
  int filter(double* r_out, double* te_out) {
    if (!started) {
      p0 = p;
      zp = Mat::Zero(k, n);
      zu = Mat::Zero(k, n);
      started = true;
    }
    xu = tf + beta;
    for (int c = 0; c < n; ++c) {
      const double x1 = p[c] - p0[c], x2 = xu[c];
      const double y1 = bp[0] * x1 + zp(0, c), y2 = bu[0] * x2 + zu(0, c);
      for (int i = 0; i < k - 1; ++i) {
        zp(i, c) = bp[i + 1] * x1 + zp(i + 1, c) - a[i + 1] * y1;
        zu(i, c) = bu[i + 1] * x2 + zu(i + 1, c) - a[i + 1] * y2;
      }
      zp(k - 1, c) = bp[k] * x1 - a[k] * y1;
      zu(k - 1, c) = bu[k] * x2 - a[k] * y2;
      r_out[c] = y1 - y2;
    }
    int flag = 0;
    const bool armed = count >= warm;
    for (size_t j = 0; j < rows.size(); ++j) {
      const double t = -r_out[rows[j]];
      te_out[j] = t;
      flag |= armed && std::fabs(t - bias[j]) > thr[j];
    }
    ++count;
    return flag;
  }

  int step(const double* q, const double* v, const double* tau, const double* bq, const double* bv, double* r_out,
           double* te_out) {
    if (k == 0) return -1;
    state(q, v, tau, bq, bv);
    dynamics(q, v);
    return filter(r_out, te_out);
  }

  void reset() {
    started = false;
    count = 0;
    for (auto& s : ps) s.p = s.s = 0.0;
  }
};

inline double now_ns() {
  return double(std::chrono::duration_cast<std::chrono::nanoseconds>(
                    std::chrono::steady_clock::now().time_since_epoch()).count());
}
}  // namespace

extern "C" {

// An observer of n coordinates on the tree of slr_model_new (taken over) with body inertias
// inertias[13 k ...] = (mass, lever (3), rotational inertia at the CoM, 3x3 row-major) of joint k+1,
// armature (nv) and gravity (3).
void* slo_new(void* tree, int n, const double* inertias, const double* armature, const double* gravity) {
  if (!tree) return nullptr;
  Model* m = static_cast<Model*>(tree);
  for (JointIndex j = 1; j < JointIndex(m->njoints); ++j) {
    const double* I = inertias + 13 * (j - 1);
    Eigen::Matrix3d R;
    R << I[4], I[5], I[6], I[7], I[8], I[9], I[10], I[11], I[12];
    m->inertias[j] = Inertia(I[0], Eigen::Vector3d(I[1], I[2], I[3]), Symmetric3(R));
  }
  for (int i = 0; i < m->nv; ++i) m->armature[i] = armature[i];
  m->gravity = Motion(Eigen::Vector3d(gravity[0], gravity[1], gravity[2]), Eigen::Vector3d::Zero());
  return new Observer(m, n);
}

void slo_free(void* h) { delete static_cast<Observer*>(h); }

// Inputs of joints: joint j of the log goes to q index jq[j] (cos/sin at jq, jq + 1 when jcont[j]),
// velocity index jv[j]; the na logged torques to observer rows act; floating: base_q → q[0:7], base_v → v[0:6].
void slo_set_joints(void* h, int nj, const int* jq, const int* jv, const int* jcont, int floating, int na,
                    const int* act) {
  auto& o = *static_cast<Observer*>(h);
  o.mode = 0;
  o.nj = nj;
  o.na = na;
  o.floating = floating;
  o.jq.assign(jq, jq + nj);
  o.jv.assign(jv, jv + nj);
  o.jcont.assign(jcont, jcont + nj);
  o.act.assign(act, act + na);
}

// A transmission: q = Gq θ + q0 (Gq nq x n), v = G θ̇ (G nv x n), M = Gᵀ M_tree G + Md (row-major).
void slo_set_transmission(void* h, const double* Gq, const double* q0, const double* G, const double* Md) {
  auto& o = *static_cast<Observer*>(h);
  const int nq = o.model->nq, nv = o.model->nv, n = o.n;
  o.mode = 1;
  o.Gq = Eigen::Map<const RowMat>(Gq, nq, n);
  o.q0 = Eigen::Map<const Vec>(q0, nq);
  o.Gv = Eigen::Map<const RowMat>(G, nv, n);
  o.Md = Eigen::Map<const RowMat>(Md, n, n);
  o.Mc = Mat::Zero(nv, n);
  o.wt = Vec::Zero(nv);
}

void slo_add_joint_friction(void* h, int iv, double eps, double rest, double vs, int product, double fv, double fc,
                            double st, double off) {
  static_cast<Observer*>(h)->jf.push_back({iv, eps, rest, vs, product, fv, fc, st, off});
}

void slo_add_presliding(void* h, int iq, int iv, double fc, double k, double play) {
  Presliding s;
  s.iq = iq;
  s.iv = iv;
  s.fc = fc;
  s.k = k;
  s.play = play;
  static_cast<Observer*>(h)->ps.push_back(s);
}

void slo_add_drive(void* h, const double* g, double fv, double fc, double off, double k, double krest, double eps,
                   double s0) {
  auto& o = *static_cast<Observer*>(h);
  o.drives.push_back({Eigen::Map<const Vec>(g, o.n), fv, fc, off, k, krest, eps, s0});
}

// The filter of order k (1 or 2): b_p, b_u, a each k + 1 coefficients (a[0] = 1).
void slo_set_filter(void* h, int k, const double* bp, const double* bu, const double* a) {
  auto& o = *static_cast<Observer*>(h);
  o.k = k;
  for (int i = 0; i <= k; ++i) {
    o.bp[i] = bp[i];
    o.bu[i] = bu[i];
    o.a[i] = a[i];
  }
  o.started = false;
}

// The collision check on m rows of r (τ_ext = −r[rows]); no contact before `warm` steps.
void slo_set_monitor(void* h, int m, const int* rows, const double* bias, const double* thr, long warm) {
  auto& o = *static_cast<Observer*>(h);
  o.rows.assign(rows, rows + m);
  o.bias = Eigen::Map<const Vec>(bias, m);
  o.thr = Eigen::Map<const Vec>(thr, m);
  o.warm = warm;
}

void slo_reset(void* h) { static_cast<Observer*>(h)->reset(); }

int slo_in_size(void* h) { return static_cast<Observer*>(h)->in_size(); }

// Buffers read and written by slo_step: in = [q, v, tau, base_q (7), base_v (6)], out = [r (n), τ_ext (m)].
void slo_bind(void* h, const double* in, double* out) {
  auto& o = *static_cast<Observer*>(h);
  o.in = in;
  o.out = out;
}

// One step on the bound buffers (use_base: base_q/base_v given). Returns the contact flag (0/1), −1 without a filter.
int slo_step(void* h, int use_base) {
  auto& o = *static_cast<Observer*>(h);
  const int w = o.mode == 0 ? o.nj : o.n, na = o.mode == 0 ? o.na : o.n;
  const double* b = o.in + 2 * w + na;
  return o.step(o.in, o.in + w, o.in + 2 * w, use_base ? b : nullptr, use_base ? b + 7 : nullptr, o.out,
                o.out + o.n);
}

// N steps over rows of IN (N x in_size, layout of slo_bind), r into R (N x n), τ_ext into TE (N x m),
// flags into F; with ns, the wall time of each step [ns].
int slo_run(void* h, int N, const double* IN, int use_base, double* R, double* TE, int* F, double* ns) {
  auto& o = *static_cast<Observer*>(h);
  const int s = o.in_size(), w = o.mode == 0 ? o.nj : o.n, na = o.mode == 0 ? o.na : o.n, m = int(o.rows.size());
  for (int i = 0; i < N; ++i) {
    const double* in = IN + size_t(i) * s;
    const double* b = in + 2 * w + na;
    const double t0 = ns ? now_ns() : 0.0;
    const int f = o.step(in, in + w, in + 2 * w, use_base ? b : nullptr, use_base ? b + 7 : nullptr,
                         R + size_t(i) * o.n, TE + size_t(i) * m);
    if (ns) ns[i] = now_ns() - t0;
    if (f < 0) return f;
    F[i] = f;
  }
  return 0;
}

// The Pinocchio state (q, v) of one input row (layout of slo_bind).
void slo_tree_state(void* h, const double* in, int use_base, double* q, double* v) {
  auto& o = *static_cast<Observer*>(h);
  const int w = o.mode == 0 ? o.nj : o.n, na = o.mode == 0 ? o.na : o.n;
  const double* b = in + 2 * w + na;
  o.state(in, in + w, in + 2 * w, use_base ? b : nullptr, use_base ? b + 7 : nullptr);
  Eigen::Map<Vec>(q, o.model->nq) = o.qf;
  Eigen::Map<Vec>(v, o.model->nv) = o.vf;
}

// The bare computation over N Pinocchio states: M (crba), Cᵀv (computeCoriolisMatrix) and g
// (computeGeneralizedGravity), into MCG (N x (nv² + 2 nv): M upper, Cᵀv, g) when given; per-sample ns.
void slo_bare(void* h, int N, const double* Q, const double* V, double* MCG, double* ns) {
  auto& o = *static_cast<Observer*>(h);
  const Model& m = *o.model;
  Data d(m);
  const int nq = m.nq, nv = m.nv;
  Vec ctv(nv);
  for (int i = 0; i < N; ++i) {
    const Eigen::Map<const Vec> q(Q + size_t(i) * nq, nq), v(V + size_t(i) * nv, nv);
    const double t0 = ns ? now_ns() : 0.0;
    crba(m, d, q);
    computeCoriolisMatrix(m, d, q, v);
    ctv.noalias() = d.C.transpose() * v;
    computeGeneralizedGravity(m, d, q);
    if (ns) ns[i] = now_ns() - t0;
    if (MCG) {
      double* out = MCG + size_t(i) * (nv * nv + 2 * nv);
      Eigen::Map<RowMat>(out, nv, nv) = d.M;
      Eigen::Map<Vec>(out + nv * nv, nv) = ctv;
      Eigen::Map<Vec>(out + nv * nv + nv, nv) = d.g;
    }
  }
}
}
