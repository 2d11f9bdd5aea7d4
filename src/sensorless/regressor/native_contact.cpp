// Batched contact null-space projector P = I - Jc^+ Jc (sensorless.regressor.contact_kinematics), compiled
// into the same library as native_kernel.cpp (sensorless.regressor.native). Plain loops, no Pinocchio.
//
// Per sample (Jc row-major m x nv): G = Jc Jc^T = L L^T, X = L^{-1} Jc, P = I - X^T X (= I - Jc^T G^{-1} Jc),
// as in the NumPy path. An exactly zero row gets the pivot G_jj = ||Jc||_F^2 (its X row is zero).
// ok[i] = 1 when ||Jc||_F ||L^{-1}||_F (>= cond(Jc)) is at most max_cond and below 1/rcond: pinv(Jc, rcond)
// keeps every row and the normal equations are accurate (error ~ eps cond^2). Otherwise (dependent rows,
// non-finite input) ok[i] = 0 and the caller redoes the sample (sensorless uses the SVD there).
// Four samples are processed together, one per vector lane (GCC/Clang vector extensions): the small
// triangular solves are latency-bound chains per sample, independent across samples.
#include <cmath>
#include <cstddef>
#include <vector>

namespace {

#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__)
#define SLR_CLONES __attribute__((target_clones("arch=haswell", "default")))
#else
#define SLR_CLONES
#endif

constexpr int W = 4;  // samples per vector
typedef double vd __attribute__((vector_size(W * sizeof(double))));

SLR_CLONES
void projector_chunk(long n, int m, int nv, const double* J, double rcond, double max_cond, double* P,
                     unsigned char* ok) {
  std::vector<vd> Jb(static_cast<size_t>(m) * nv), L(static_cast<size_t>(m) * m), Li(static_cast<size_t>(m) * m),
      X(static_cast<size_t>(m) * nv), Pb(static_cast<size_t>(nv) * nv), rinv(m);
  const size_t sJ = static_cast<size_t>(m) * nv, sP = static_cast<size_t>(nv) * nv;
  for (long s0 = 0; s0 < n; s0 += W) {
    const int lanes = static_cast<int>(n - s0 < W ? n - s0 : W);
    // gather W samples, samples innermost (a missing lane repeats the first sample)
    for (int b = 0; b < W; ++b) {
      const double* Js = J + (s0 + (b < lanes ? b : 0)) * sJ;
      for (size_t i = 0; i < sJ; ++i) Jb[i][b] = Js[i];
    }
    // G = J J^T (lower) into L, s2 = ||J||_F^2
    vd s2 = {0, 0, 0, 0};
    for (int j = 0; j < m; ++j) {
      for (int k = 0; k <= j; ++k) {
        vd d = {0, 0, 0, 0};
        const vd* a = &Jb[j * nv];
        const vd* c = &Jb[k * nv];
        for (int i = 0; i < nv; ++i) d += a[i] * c[i];
        L[j * m + k] = d;
      }
      s2 += L[j * m + j];
    }
    const vd zero = {0, 0, 0, 0}, one = {1, 1, 1, 1};
    const vd scale2 = s2 > zero ? s2 : one;
    bool good[W];
    for (int b = 0; b < W; ++b) good[b] = std::isfinite(s2[b]);
    // Cholesky in place; zero rows get the pivot ||J||_F
    for (int j = 0; j < m; ++j) {
      vd* lj = &L[j * m];
      lj[j] = lj[j] == zero ? scale2 : lj[j];
      for (int k = 0; k < j; ++k) {
        const vd* lk = &L[k * m];
        vd v = lj[k];
        for (int l = 0; l < k; ++l) v -= lj[l] * lk[l];
        lj[k] = v * rinv[k];
      }
      vd d = lj[j];
      for (int l = 0; l < j; ++l) d -= lj[l] * lj[l];
      for (int b = 0; b < W; ++b) {
        if (!(d[b] > 0.0)) {
          good[b] = false;
          d[b] = 1.0;
        }
        d[b] = std::sqrt(d[b]);
      }
      lj[j] = d;
      rinv[j] = one / d;
    }
    // L^{-1} and its squared Frobenius norm
    vd t2 = zero;
    for (int j = 0; j < m; ++j) {
      vd* row = &Li[j * m];
      for (int k = 0; k <= j; ++k) row[k] = zero;
      for (int l = 0; l < j; ++l) {
        const vd a = L[j * m + l];
        const vd* rl = &Li[l * m];
        for (int k = 0; k <= l; ++k) row[k] += a * rl[k];
      }
      const vd inv = rinv[j];
      for (int k = 0; k < j; ++k) row[k] *= -inv;
      row[j] = inv;
      for (int k = 0; k <= j; ++k) t2 += row[k] * row[k];
    }
    const vd k2 = s2 * t2;
    // X = L^{-1} J
    for (int j = 0; j < m; ++j) {
      vd* x = &X[j * nv];
      const vd* lj = &Li[j * m];
      for (int c = 0; c < nv; ++c) x[c] = lj[0] * Jb[c];
      for (int k = 1; k <= j; ++k) {
        const vd a = lj[k];
        const vd* r = &Jb[k * nv];
        for (int c = 0; c < nv; ++c) x[c] += a * r[c];
      }
    }
    // P = I - X^T X (lower triangle, mirrored on the way out)
    for (int a = 0; a < nv; ++a) {
      vd* row = &Pb[a * nv];
      for (int c = 0; c <= a; ++c) row[c] = zero;
      for (int j = 0; j < m; ++j) {
        const vd* x = &X[j * nv];
        const vd xa = x[a];
        for (int c = 0; c <= a; ++c) row[c] -= xa * x[c];
      }
      row[a] += one;
    }
    for (int b = 0; b < lanes; ++b) {
      double* Ps = P + (s0 + b) * sP;
      if (!good[b]) {
        ok[s0 + b] = 0;
        for (size_t i = 0; i < sP; ++i) Ps[i] = NAN;
        continue;
      }
      ok[s0 + b] = (k2[b] <= max_cond * max_cond) && (k2[b] * rcond * rcond < 1.0);
      for (int a = 0; a < nv; ++a)
        for (int c = 0; c <= a; ++c) Ps[a * nv + c] = Ps[c * nv + a] = Pb[a * nv + c][b];
    }
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
