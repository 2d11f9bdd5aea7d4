// Candidate friction columns of the law search (sensorless.identification.stribeck.StribeckCandidates),
// compiled into the same library as native_kernel.cpp (sensorless.regressor.native). Plain loops.
//
// Per sample i and term joint j (velocity v = V[i, j]), into out + i*si + j*sj (contiguous columns):
//   T_g = tanh(v / w_g) * t_mask[i, j]          (sgn v for w_g <= 0)            g < n_w
//   D_h = expm1(-(v / vs_h)^2) * d_sign[i, j]   (d_sign = -sgn v, 0 at rest)     h < n_s
// the element-wise operations of the NumPy route. Most arguments are far in the saturated range on a
// moving joint (|v/w| >= 20: tanh is +-1 to the last bit, e^{-40} < 2^-54; (v/vs)^2 >= 40: expm1 is -1
// to the last bit), where no libm call is made (about 0.9 of the width and 0.6 of the decay columns on
// the UR5 benchmark log). Elsewhere, away from 0, the faster exp gives both to about 2 ulp:
// tanh |u| = (1 - e)/(1 + e), e = e^{-2|u|} <= e^{-1} (no cancellation), and expm1(-u) = e^{-u} - 1 for
// u >= ln 2 (Sterbenz: the subtraction is exact); near 0 glibc's tanh and expm1. v/w is v times the
// reciprocal 1/w (1 ulp; 228 scalar divisions per UR5 sample were half of the kernel's time).
#include <cmath>
#include <vector>

extern "C" {

void slr_friction_candidates(long n, int n_joints, const double* v, const double* t_mask, const double* d_sign,
                             int n_w, const double* widths, int n_s, const double* vs, double* out, long si,
                             long sj) {
  std::vector<double> rw(size_t(n_joints) * n_w), rs(size_t(n_joints) * n_s);
  for (size_t k = 0; k < rw.size(); ++k) rw[k] = widths[k] > 0 ? 1.0 / widths[k] : 0.0;
  for (size_t k = 0; k < rs.size(); ++k) rs[k] = 1.0 / vs[k];
  for (long i = 0; i < n; ++i) {
    for (int j = 0; j < n_joints; ++j) {
      const long k = i * n_joints + j;
      const double x = v[k], tm = t_mask[k], ds = d_sign[k];
      double* o = out + i * si + j * sj;
      const double* w = widths + long(j) * n_w;
      const double* r = rw.data() + long(j) * n_w;
      for (int g = 0; g < n_w; ++g) {
        double t;
        if (w[g] > 0) {
          const double u = x * r[g];
          const double a = std::fabs(u);
          if (a >= 20.0) {
            t = 1.0;
          } else if (a >= 0.5) {
            const double e = std::exp(-2.0 * a);
            t = (1.0 - e) / (1.0 + e);
          } else {
            t = std::tanh(a);
          }
          t = u < 0 ? -t : t;
        } else {
          t = double((x > 0) - (x < 0));
        }
        o[g] = t * tm;
      }
      const double* s = rs.data() + long(j) * n_s;
      for (int h = 0; h < n_s; ++h) {
        double u = x * s[h];
        u = u * u;
        o[n_w + h] = (u >= 40.0 ? -1.0 : (u >= 0.6931471805599453 ? std::exp(-u) - 1.0 : std::expm1(-u))) * ds;
      }
    }
  }
}
}
