#include "mpm/materials.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <sstream>

namespace mpm {

namespace {
void require(bool ok, const Material& m, const std::string& what) {
  if (!ok) throw UserError("material \"" + m.name + "\": " + what);
}
}  // namespace

MaterialModel::MaterialModel(const Material& m) : kind(m.model), density(m.density), mu_i(m.mu_i) {
  const double E = m.model == ModelKind::DruckerPrager ? m.drucker_prager.youngs_modulus : m.mu_i.youngs_modulus;
  const double nu = m.model == ModelKind::DruckerPrager ? m.drucker_prager.poisson_ratio : m.mu_i.poisson_ratio;
  require(density > 0, m, "density must be > 0");
  require(E > 0, m, "youngs_modulus must be > 0");
  require(nu >= 0 && nu < 0.5, m, "poisson_ratio must be in [0, 0.5)");
  shear_modulus = E / (2.0 * (1.0 + nu));
  lame_lambda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
  if (kind == ModelKind::DruckerPrager) {
    const double phi = m.drucker_prager.friction_angle_deg;
    require(phi > 0 && phi < 90, m, "friction_angle must be in (0, 90) degrees");
    friction_angle_rad = phi * M_PI / 180.0;
    const double G = shear_modulus, lam = lame_lambda;
    cone_strain_slope[0] = cone_slope<2>() * (2 * lam + 2 * G) / (2 * G * 2);
    cone_strain_slope[1] = cone_slope<3>() * (3 * lam + 2 * G) / (2 * G * 3);
  } else {
    require(mu_i.mu_s > 0 && mu_i.mu_2 > mu_i.mu_s, m, "mu(I) needs 0 < mu_s < mu_2");
    require(mu_i.I0 > 0 && mu_i.grain_diameter > 0 && mu_i.grain_density > 0, m,
            "I0, grain_diameter and grain_density must be > 0");
    require(mu_i.critical_density > 0 && mu_i.critical_density <= mu_i.grain_density, m,
            "critical_density must be in (0, grain_density]");
  }
}

// Tensor log and exp of symmetric tensors. Elastic strains of granular
// continua are small (|eps| ~ 1e-3), so near identity / zero a truncated series
// is used (relative error below r^5/6 = 2e-11 at the radius r); elsewhere the
// spectral definition: closed form in 2D, eigen-decomposition in 3D. Both give
// the same tensor; the series is several times cheaper.
namespace {

constexpr double kSeriesRadius = 0.01;

template <int D>
Mat<D> series_log(const Mat<D>& X) {  // log(I + X)
  const Mat<D> I = Mat<D>::Identity();
  // X - X^2/2 + X^3/3 - X^4/4 + X^5/5, Horner form. Each step builds a new
  // matrix: `acc = I - X * acc` would alias in Eigen's lazy small products.
  // (Reciprocals multiply: a divide per entry costs as much as the products.)
  const Mat<D> a4 = 0.25 * I - 0.2 * X;
  const Mat<D> a3 = (1.0 / 3.0) * I - X * a4;
  const Mat<D> a2 = 0.5 * I - X * a3;
  const Mat<D> a1 = I - X * a2;
  return X * a1;
}

template <int D>
Mat<D> series_exp(const Mat<D>& y) {
  const Mat<D> I = Mat<D>::Identity();
  // I + y + y^2/2 + ... + y^6/720, Horner form.
  const Mat<D> a6 = I + (1.0 / 6.0) * y;
  const Mat<D> a5 = I + (0.2 * y) * a6;
  const Mat<D> a4 = I + (0.25 * y) * a5;
  const Mat<D> a3 = I + ((1.0 / 3.0) * y) * a4;
  const Mat<D> a2 = I + (0.5 * y) * a3;
  return I + y * a2;
}

// In 2D every function f of a symmetric tensor M is alpha I + beta M, with
// beta the divided difference (f(l1) - f(l2)) / (l1 - l2) of its eigenvalues
// l = m +- h. Near-equal eigenvalues use the series of the divided difference.
struct Spectrum2 {
  double m, h;  // mean and half-difference of the eigenvalues
  explicit Spectrum2(const Mat<2>& a) : m(0.5 * (a(0, 0) + a(1, 1))) {
    const double d = 0.5 * (a(0, 0) - a(1, 1));
    h = std::sqrt(d * d + a(0, 1) * a(0, 1));  // not hypot: strains never overflow, and hypot is slow
  }
};

Mat<2> spectral_log(const Mat<2>& b) {
  const Spectrum2 s(b);
  const double x = s.h / s.m;
  // beta = (log(m+h) - log(m-h)) / 2h = atanh(x) / (x m)
  const double atanh_over_x = x < 1e-4 ? 1.0 + x * x / 3.0 : std::atanh(x) / x;
  const double beta = atanh_over_x / s.m;
  const double alpha = 0.5 * std::log((s.m - s.h) * (s.m + s.h)) - beta * s.m;
  return alpha * Mat<2>::Identity() + beta * b;
}

Mat<2> spectral_exp(const Mat<2>& y) {
  const Spectrum2 s(y);
  // beta = (e^(m+h) - e^(m-h)) / 2h = e^m sinh(h) / h; sinh and cosh from one
  // expm1, without cancellation for small h.
  const double e1 = std::expm1(s.h), eh = 1.0 + e1;
  const double sinh_h = 0.5 * e1 * (1.0 + 1.0 / eh), cosh_h = 1.0 + 0.5 * e1 * e1 / eh;
  const double sinh_over_h = s.h < 1e-4 ? 1.0 + s.h * s.h / 6.0 : sinh_h / s.h;
  const double em = std::exp(s.m);
  const double beta = em * sinh_over_h;
  const double alpha = em * cosh_h - beta * s.m;
  return alpha * Mat<2>::Identity() + beta * y;
}

Mat<3> spectral_log(const Mat<3>& b) {
  Eigen::SelfAdjointEigenSolver<Mat<3>> eig;
  eig.computeDirect(b);
  const Vec<3> logs = eig.eigenvalues().cwiseMax(1e-300).array().log();
  return eig.eigenvectors() * logs.asDiagonal() * eig.eigenvectors().transpose();
}

Mat<3> spectral_exp(const Mat<3>& y) {
  Eigen::SelfAdjointEigenSolver<Mat<3>> eig;
  eig.computeDirect(y);
  const Vec<3> exps = eig.eigenvalues().array().exp();
  return eig.eigenvectors() * exps.asDiagonal() * eig.eigenvectors().transpose();
}

}  // namespace

template <int D>
Mat<D> tensor_log(const Mat<D>& b) {
  const Mat<D> X = b - Mat<D>::Identity();
  return X.squaredNorm() <= kSeriesRadius * kSeriesRadius ? series_log<D>(X) : spectral_log(b);
}

template <int D>
Mat<D> tensor_exp(const Mat<D>& y) {
  return y.squaredNorm() <= 4.0 * kSeriesRadius * kSeriesRadius ? series_exp<D>(y) : spectral_exp(y);
}

template <int D>
void update_drucker_prager(const MaterialModel& m, const Mat<D>& f, Mat<D>& be, Mat<D>& stress,
                           double& plastic_strain) {
  const Mat<D> I = Mat<D>::Identity();
  // Hencky strain of the elastic trial state. The return map below acts on its
  // trace and deviator only, so it can stay in tensor form (eps and be share
  // principal axes).
  const Mat<D> trial = f * be * f.transpose();
  Mat<D> eps = 0.5 * tensor_log<D>(trial);
  const double tr = eps.trace();
  const Mat<D> dev = eps - (tr / D) * I;
  const double dev_norm = dev.norm();
  const double G = m.shear_modulus, lam = m.lame_lambda;

  if (tr >= 0.0) {
    // Dilation: grains lose contact; cohesionless material carries no stress.
    plastic_strain += std::sqrt(2.0) * dev_norm;
    be.setIdentity();
    stress.setZero();
    return;
  }
  // Yield: 2G |dev eps| <= alpha * p, p = -(D lam + 2G)/D * tr eps.
  const double delta_gamma = dev_norm + m.cone_strain_slope[D - 2] * tr;
  if (delta_gamma > 0.0) {
    eps -= (delta_gamma / dev_norm) * dev;  // dev_norm > 0 whenever delta_gamma > 0 here
    plastic_strain += std::sqrt(2.0) * delta_gamma;
    be = tensor_exp<D>(2.0 * eps);
  } else {
    be = trial;  // elastic: exp(2 eps) is the trial state itself
  }
  // J_e = exp(tr eps) = sqrt(det b) (cheaper than exp); the return is isochoric.
  const double Je = std::sqrt(trial.determinant());
  stress = (2.0 * G * eps + lam * tr * I) / Je;
}

template <int D>
void update_mu_i(const MaterialModel& m, const Mat<D>& L, double dt, double density, Mat<D>& stress,
                 double& plastic_strain) {
  const auto& p = m.mu_i;
  if (density < p.critical_density) {
    stress.setZero();  // disconnected: grains no longer touch
    return;
  }
  const Mat<D> Drate = 0.5 * (L + L.transpose());
  const Mat<D> W = 0.5 * (L - L.transpose());
  const Mat<D> I = Mat<D>::Identity();
  const double G = m.shear_modulus, lam = m.lame_lambda;
  // Elastic trial with the Jaumann rate: sigma_dot = C:D + W sigma - sigma W.
  const Mat<D> trial = stress + dt * (2.0 * G * Drate + lam * Drate.trace() * I + W * stress - stress * W);
  const double pressure = -trial.trace() / D;
  if (pressure <= 0.0) {
    stress.setZero();  // no tension
    return;
  }
  const Mat<D> dev = trial + pressure * I;
  const double tau_trial = dev.norm() / std::sqrt(2.0);
  const double excess = tau_trial - p.mu_s * pressure;
  if (excess <= 0.0) {
    stress = trial;
    return;
  }
  // Plastic flow: find u = tau_trial - tau = G dt gammadot_p >= 0 such that
  // tau / p = mu(I), I = gammadot_p d / sqrt(p / rho_s). With beta = I per unit u,
  // this is beta u^2 + B u - excess I0 = 0, B = I0 + beta ((mu_2 - mu_s) p - excess).
  const double beta = p.grain_diameter * std::sqrt(p.grain_density / pressure) / (G * dt);
  const double B = p.I0 + beta * ((p.mu_2 - p.mu_s) * pressure - excess);
  const double disc = std::sqrt(B * B + 4.0 * beta * excess * p.I0);
  const double u = B >= 0.0 ? 2.0 * excess * p.I0 / (B + disc) : (disc - B) / (2.0 * beta);
  const double tau = std::max(tau_trial - u, 0.0);
  stress = dev * (tau / tau_trial) - pressure * I;
  plastic_strain += u / G;  // gammadot_p * dt
}

template <int D>
Mat<D> elastic_state_for_stress(const MaterialModel& m, const Mat<D>& stress) {
  // Small-strain inverse of tau = 2G eps + lam tr(eps) I, taking tau ~ sigma.
  const double G = m.shear_modulus, lam = m.lame_lambda;
  const double tr_eps = stress.trace() / (D * lam + 2.0 * G);
  const Mat<D> eps = (stress - lam * tr_eps * Mat<D>::Identity()) / (2.0 * G);
  return tensor_exp<D>(2.0 * eps);
}

template void update_drucker_prager<2>(const MaterialModel&, const Mat<2>&, Mat<2>&, Mat<2>&, double&);
template void update_drucker_prager<3>(const MaterialModel&, const Mat<3>&, Mat<3>&, Mat<3>&, double&);
template void update_mu_i<2>(const MaterialModel&, const Mat<2>&, double, double, Mat<2>&, double&);
template void update_mu_i<3>(const MaterialModel&, const Mat<3>&, double, double, Mat<3>&, double&);
template Mat<2> tensor_log<2>(const Mat<2>&);
template Mat<3> tensor_log<3>(const Mat<3>&);
template Mat<2> tensor_exp<2>(const Mat<2>&);
template Mat<3> tensor_exp<3>(const Mat<3>&);
template Mat<2> elastic_state_for_stress<2>(const MaterialModel&, const Mat<2>&);
template Mat<3> elastic_state_for_stress<3>(const MaterialModel&, const Mat<3>&);

}  // namespace mpm
