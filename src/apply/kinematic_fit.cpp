#include "emcalign/apply/kinematic_fit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

#include "emcalign/geometry/track.hpp"

namespace emcalign::apply {

namespace {

using Measured = Eigen::Matrix<double, 10, 1>;
using Constraints = Eigen::Matrix<double, 4, 1>;
using DerivM = Eigen::Matrix<double, 4, 10>;
using DerivU = Eigen::Matrix<double, 4, 2>;

Vec3 direction(double theta, double phi) { return geometry::pointAt(1.0, theta, phi); }
Vec3 dTheta(double theta, double phi) {
  return {std::cos(theta) * std::cos(phi), std::cos(theta) * std::sin(phi), -std::sin(theta)};
}
Vec3 dPhi(double theta, double phi) { return {-std::sin(theta) * std::sin(phi), std::sin(theta) * std::cos(phi), 0.0}; }

// The constraints f = (ΣE − E_tot, Σp − P_tot) at (m, u), and their derivatives.
void constraints(const Measured& m, const Eigen::Vector2d& u, const ThreePionEvent& e, double mass, Constraints& f,
                 DerivM& b, DerivU& a) {
  f.setZero();
  b.setZero();
  a.setZero();
  f[0] = -e.totalEnergy;
  f.tail<3>() = -e.totalMomentum;
  for (int i = 0; i < 2; ++i) {  // photons: E, θ, φ at 3i
    const double energy = m[3 * i], theta = m[3 * i + 1], phi = m[3 * i + 2];
    const Vec3 n = direction(theta, phi);
    f[0] += energy;
    f.tail<3>() += energy * n;
    b(0, 3 * i) = 1.0;
    b.block<3, 1>(1, 3 * i) = n;
    b.block<3, 1>(1, 3 * i + 1) = energy * dTheta(theta, phi);
    b.block<3, 1>(1, 3 * i + 2) = energy * dPhi(theta, phi);
  }
  for (int j = 0; j < 2; ++j) {  // pions: θ, φ at 6 + 2j, momentum u[j]
    const double theta = m[6 + 2 * j], phi = m[7 + 2 * j], p = u[j];
    const Vec3 n = direction(theta, phi);
    const double energy = std::sqrt(p * p + mass * mass);
    f[0] += energy;
    f.tail<3>() += p * n;
    b.block<3, 1>(1, 6 + 2 * j) = p * dTheta(theta, phi);
    b.block<3, 1>(1, 7 + 2 * j) = p * dPhi(theta, phi);
    a(0, j) = p / energy;
    a.block<3, 1>(1, j) = n;
  }
}

// Starting momenta: the pions balance the photons' momentum (least squares over the three
// components); where that fails, the energy left shared between them.
Eigen::Vector2d startingMomenta(const Measured& m, const ThreePionEvent& e, double mass) {
  Vec3 missing = e.totalMomentum;
  double energyLeft = e.totalEnergy;
  for (int i = 0; i < 2; ++i) {
    missing -= m[3 * i] * direction(m[3 * i + 1], m[3 * i + 2]);
    energyLeft -= m[3 * i];
  }
  Eigen::Matrix<double, 3, 2> n;
  n.col(0) = direction(m[6], m[7]);
  n.col(1) = direction(m[8], m[9]);
  Eigen::Vector2d p = n.colPivHouseholderQr().solve(missing);
  const double share = std::max(energyLeft / 2.0, mass * 1.01);
  const double fallback = std::sqrt(share * share - mass * mass);
  for (int j = 0; j < 2; ++j) {
    if (!(std::isfinite(p[j]) && p[j] > 1.0)) p[j] = fallback;
  }
  return p;
}

}  // namespace

KinematicFitResult fitThreePion(const ThreePionEvent& e, const KinematicFitOptions& o) {
  KinematicFitResult r;
  Measured m0, sigma;
  for (int i = 0; i < 2; ++i) {
    const auto& g = e.photons[static_cast<std::size_t>(i)];
    m0.segment<3>(3 * i) << g.energy, g.theta, g.phi;
    sigma.segment<3>(3 * i) << g.sigmaEnergy, g.sigmaTheta, g.sigmaPhi;
  }
  for (int j = 0; j < 2; ++j) {
    const auto& t = e.pions[static_cast<std::size_t>(j)];
    m0.segment<2>(6 + 2 * j) << t.theta, t.phi;
    sigma.segment<2>(6 + 2 * j) << t.sigmaTheta, t.sigmaPhi;
  }
  if (!(m0.allFinite() && sigma.allFinite() && (sigma.array() > 0.0).all() && std::isfinite(e.totalEnergy))) {
    return r;
  }
  const Measured variance = sigma.array().square();
  Measured m = m0;
  Eigen::Vector2d u = startingMomenta(m0, e, o.chargedPionMass);
  Constraints f;
  DerivM b;
  DerivU a;
  double chi2 = std::numeric_limits<double>::infinity();
  for (int iteration = 1; iteration <= o.maxIterations; ++iteration) {
    r.iterations = iteration;
    constraints(m, u, e, o.chargedPionMass, f, b, a);
    const Constraints residual = f + b * (m0 - m);
    const Eigen::Matrix4d s = b * variance.asDiagonal() * b.transpose();
    const Eigen::LDLT<Eigen::Matrix4d> sInverse(s);
    if (sInverse.info() != Eigen::Success) return r;
    const DerivU sa = sInverse.solve(a);
    const Eigen::Matrix2d aSa = a.transpose() * sa;
    const Eigen::Vector2d du = -aSa.ldlt().solve(sa.transpose() * residual);
    const Constraints lambda = sInverse.solve(residual + a * du);
    const Measured dm = -(variance.asDiagonal() * (b.transpose() * lambda));
    m = m0 + dm;
    u += du;
    if (!(m.allFinite() && u.allFinite()) || u.minCoeff() <= 0.0 || m[0] <= 0.0 || m[3] <= 0.0) return r;
    const double newChi2 = (dm.array().square() / variance.array()).sum();
    constraints(m, u, e, o.chargedPionMass, f, b, a);
    r.maxConstraint = f.cwiseAbs().maxCoeff();
    const bool settled = std::abs(newChi2 - chi2) < std::max(1e-9, 1e-6 * newChi2);
    chi2 = newChi2;
    if (settled && r.maxConstraint < 1e-6) {
      r.converged = true;
      break;
    }
  }
  r.chi2 = chi2;
  r.pValue = std::exp(-0.5 * chi2);
  for (int k = 0; k < 10; ++k) r.fitted[static_cast<std::size_t>(k)] = m[k];
  r.pionMomenta = {u[0], u[1]};
  return r;
}

}  // namespace emcalign::apply
