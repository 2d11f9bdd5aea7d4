// Batched contact null-space projector P = I - Jc^+ Jc (sensorless.regressor.contact_kinematics), compiled
// into the same library as native_kernel.cpp (sensorless.regressor.native). Plain loops, no Pinocchio.
//
// Per sample (Jc row-major m x nv): G = Jc Jc^T = L L^T, X = L^{-1} Jc, P = I - X^T X (= I - Jc^T G^{-1} Jc),
// as in the NumPy path. An exactly zero row gets the pivot G_jj = ||Jc||_F^2 (its X row is zero). ok[i] = 1 when ||Jc||_F ||L^{-1}||_F (>= cond(Jc)) is at most max_cond and below 1/rcond:
// pinv(Jc, rcond) keeps every row and the normal equations are accurate (error ~ eps cond^2). Otherwise (dependent rows, non-finite input)
// ok[i] = 0 and the caller redoes the sample (sensorless uses the SVD there).
#include <cmath>
#include <cstddef>
#include <vector>

namespace {

#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__)
#define SLR_CLONES __attribute__((target_clones("arch=haswell", "default")))
#else
#define SLR_CLONES
#endif

// Dot product with eight independent partial sums (a vectorisable reduction).
inline double dot(const double* a, const double* b, int n) {
  double acc[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int c = 0;
  for (; c + 8 <= n; c += 8)
    for (int u = 0; u < 8; ++u) acc[u] += a[c + u] * b[c + u];
  for (; c < n; ++c) acc[0] += a[c] * b[c];
  return ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
}

SLR_CLONES
void projector_chunk(long n, int m, int nv, const double* J, double rcond, double max_cond, double* P,
                     unsigned char* ok) {
  const size_t mm = static_cast<size_t>(m) * m;
  std::vector<double> L(mm), Li(mm), Xv(static_cast<size_t>(m) * nv), rinv(m);
  double* __restrict X = Xv.data();
  for (long s = 0; s < n; ++s) {
    const double* __restrict Js = J + static_cast<size_t>(s) * m * nv;
    double* __restrict Ps = P + static_cast<size_t>(s) * nv * nv;
    // G = J J^T (lower triangle, independent dot products) into L
    double s2 = 0.0;
    for (int j = 0; j < m; ++j) {
      for (int k = 0; k <= j; ++k) L[j * m + k] = dot(Js + j * nv, Js + k * nv, nv);
      s2 += L[j * m + j];
    }
    const double scale2 = s2 > 0.0 ? s2 : 1.0;
    bool good = std::isfinite(s2);
    // Cholesky G = L L^T in place (rinv: reciprocal pivots); a zero row (G_jj = 0) gets the pivot ||J||_F
    for (int j = 0; j < m && good; ++j) {
      double* lj = L.data() + j * m;
      if (lj[j] == 0.0) lj[j] = scale2;
      for (int k = 0; k < j; ++k) {
        const double* lk = L.data() + k * m;
        double v = lj[k];
        for (int l = 0; l < k; ++l) v -= lj[l] * lk[l];
        lj[k] = v * rinv[k];
      }
      double d = lj[j];
      for (int l = 0; l < j; ++l) d -= lj[l] * lj[l];
      if (!(d > 0.0)) {
        good = false;
      } else {
        lj[j] = std::sqrt(d);
        rinv[j] = 1.0 / lj[j];
      }
    }
    if (!good) {
      ok[s] = 0;
      for (int i = 0; i < nv * nv; ++i) Ps[i] = NAN;
      continue;
    }
    // L^{-1} (lower, row by row: row_j = -(sum_l L_jl row_l) / L_jj) and its squared Frobenius norm
    double t2 = 0.0;
    for (int j = 0; j < m; ++j) {
      double* __restrict row = Li.data() + j * m;
      for (int k = 0; k <= j; ++k) row[k] = 0.0;
      for (int l = 0; l < j; ++l) {
        const double a = L[j * m + l];
        const double* rl = Li.data() + l * m;
        for (int k = 0; k <= l; ++k) row[k] += a * rl[k];
      }
      const double inv = rinv[j];
      for (int k = 0; k < j; ++k) row[k] *= -inv;
      row[j] = inv;
      t2 += dot(row, row, j + 1);
    }
    const double k2 = s2 * t2;
    ok[s] = (k2 <= max_cond * max_cond) && (k2 * rcond * rcond < 1.0);
    // X = L^{-1} J (zero rows of J stay zero)
    for (int j = 0; j < m; ++j) {
      double* __restrict x = X + j * nv;
      const double* lj = Li.data() + j * m;
      for (int c = 0; c < nv; ++c) x[c] = lj[0] * Js[c];
      for (int k = 1; k <= j; ++k) {
        const double a = lj[k];
        const double* b = Js + k * nv;
        for (int c = 0; c < nv; ++c) x[c] += a * b[c];
      }
    }
    // P = I - X^T X
    for (int i = 0; i < nv * nv; ++i) Ps[i] = 0.0;
    for (int j = 0; j < m; ++j) {
      const double* x = X + j * nv;
      for (int a = 0; a < nv; ++a) {
        const double xa = x[a];
        double* __restrict row = Ps + a * nv;
        for (int c = 0; c < nv; ++c) row[c] -= xa * x[c];
      }
    }
    for (int a = 0; a < nv; ++a) Ps[a * nv + a] += 1.0;
  }
}

}  // namespace

extern "C" {

// J (n, m, nv) and P (n, nv, nv) C-contiguous doubles, ok (n) bytes.
void slr_null_space_projector(long n, int m, int nv, const double* J, double rcond, double max_cond, double* P,
                              unsigned char* ok) {
  projector_chunk(n, m, nv, J, rcond, max_cond, P, ok);
}

}  // extern "C"
