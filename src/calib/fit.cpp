#include "emcalign/calib/fit.hpp"
#include "emcalign/core/text.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <set>

#include <ceres/ceres.h>
#include <fmt/format.h>

#include <Eigen/Eigenvalues>

#include "emcalign/core/special_functions.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/residual_model.hpp"

namespace emcalign::calib {

namespace {

constexpr int kFitParams = static_cast<int>(kNumParams);

struct BinPoint {
  double phi, theta, radius, yPhi, yTheta, wPhi, wTheta;  // w = 1/σ
  double plusWeight;  // 1 or 0 (the contract: s = sign(cos φ)), or the mixture of a parting-plane response
};

// All whitened residuals in one functor: the two hemispheres' placements are built once
// per evaluation and shared by the 2·bins residuals.
struct ProfileResiduals {
  const std::vector<BinPoint>* points;
  geometry::AlignmentRadii radii;
  std::shared_ptr<const FitResponse> response;  // the model at c + R·η when set

  template <typename T>
  bool operator()(const T* const eta, T* residuals) const {
    geometry::ParamVectorT<T> p = Eigen::Map<const geometry::ParamVectorT<T>>(eta);
    if (response) {
      const geometry::ParamVectorT<T> q = p;
      response->apply(q.data(), p.data());
    }
    const auto plus = geometry::hemisphereTransform<T>(p, geometry::Hemisphere::Plus, radii);
    const auto minus = geometry::hemisphereTransform<T>(p, geometry::Hemisphere::Minus, radii);
    for (std::size_t i = 0; i < points->size(); ++i) {
      const BinPoint& b = (*points)[i];
      const auto f = geometry::mixedModelResidual<T>(plus, minus, b.phi, b.theta, b.radius, b.plusWeight);
      residuals[2 * i] = (b.yPhi - f.phi) * b.wPhi;
      residuals[2 * i + 1] = (b.yTheta - f.theta) * b.wTheta;
    }
    return true;
  }
};

std::vector<BinPoint> pointsOf(const std::vector<ProfileBin>& bins, const FitGeometry& g) {
  std::vector<BinPoint> out;
  for (const auto& b : bins) {
    if (!b.used) continue;
    const double plusWeight = std::isnan(b.plusWeight) ? (std::cos(b.phiMean) >= 0.0 ? 1.0 : 0.0) : b.plusWeight;
    out.push_back({b.phiMean, b.thetaMean, g.depth.radius(b.energyMean, b.thetaMean), b.yPhi, b.yTheta,
                   1.0 / b.sigmaPhi, 1.0 / b.sigmaTheta, plusWeight});
  }
  return out;
}

std::string paramList(const std::vector<Param>& ps) {
  std::string s;
  for (Param p : ps) s += fmt::format("{}{}", s.empty() ? "" : ", ", name(p));
  return s;
}

}  // namespace

Status FitOptions::validate() const {
  std::set<Param> all;
  for (const auto& stage : stages) all.insert(stage.begin(), stage.end());
  if (all.size() != kNumParams) return Error{"fit: the stages must free all 12 parameters"};
  if (maxIterations < 1) return Error{"fit: maxIterations must be positive"};
  return {};
}

geometry::AngularResidual modelAt(const FitGeometry& g, const geometry::ParamVector& eta, double phi, double theta,
                                  double energy) {
  return geometry::modelResidual<double>(g.modelParameters(eta), g.radii, g.depth, phi, theta, energy);
}

double chi2At(const std::vector<ProfileBin>& bins, const FitGeometry& g, const geometry::ParamVector& eta) {
  const auto points = pointsOf(bins, g);
  ProfileResiduals f{&points, g.radii, g.response};
  std::vector<double> r(2 * points.size());
  f(eta.data(), r.data());
  double chi2 = 0.0;
  for (double x : r) chi2 += x * x;
  return chi2;
}

namespace {

using Jacobian = Eigen::Matrix<double, Eigen::Dynamic, kFitParams, Eigen::RowMajor>;

// The Jacobian of the whitened residuals at η; none when the cost cannot be evaluated.
std::optional<Jacobian> jacobianAt(const ceres::CostFunction& cost, const geometry::ParamVector& eta) {
  const auto rows = static_cast<std::size_t>(cost.num_residuals());
  std::vector<double> residuals(rows);
  Jacobian jacobian(static_cast<Eigen::Index>(rows), kFitParams);
  double* jac[1] = {jacobian.data()};
  const double* params[1] = {eta.data()};
  if (!cost.Evaluate(params, residuals.data(), jac)) return std::nullopt;
  return jacobian;
}

void setCovariance(FitResult& result, const Covariance& covariance) {
  result.covariance = covariance;
  for (int k = 0; k < kFitParams; ++k) result.errors[k] = std::sqrt(covariance(k, k));
  for (int i = 0; i < kFitParams; ++i) {
    for (int j = 0; j < kFitParams; ++j)
      result.correlation(i, j) = covariance(i, j) / (result.errors[i] * result.errors[j]);
  }
}

// The physical parameters, errors by the Jacobian of physicalOf (automatic differentiation),
// from the covariance and, when known, the statistical covariance.
void setDerived(FitResult& result, double r1) {
  using Jet = ceres::Jet<double, kFitParams>;
  geometry::ParamVectorT<Jet> etaJet;
  for (int k = 0; k < kFitParams; ++k) etaJet[k] = Jet(result.parameters.values[k], k);
  const auto physical = geometry::physicalOf<Jet>(etaJet, r1);
  const auto propagated = [](const std::optional<Covariance>& c, const Eigen::Matrix<double, kFitParams, 1>& grad) {
    return c && grad.allFinite() ? std::sqrt(grad.dot(*c * grad)) : std::numeric_limits<double>::quiet_NaN();
  };
  for (Physical p : kAllPhysical) {
    const Jet& x = physical[index(p)];
    DerivedValue& v = result.derived[p];
    v.value = x.a;
    const Eigen::Matrix<double, kFitParams, 1> grad = x.v;
    v.error = propagated(result.covariance, grad);
    v.statisticalError = propagated(result.statisticalCovariance, grad);
  }
}

// Jᵀ·R·J + Jᵀ·C·J of the whitened residuals: `scale[i]` the diagonal R (1: the independent
// bins' JᵀJ), C the bins' correlations, each scaled by the two residuals' weights.
Result<Covariance> sandwichMiddle(const Jacobian& jacobian, const std::vector<double>& scale,
                                  const std::vector<BinPoint>& points, const std::vector<ProfileBin>& bins,
                                  const std::vector<BinCovariance>& covariances) {
  Covariance middle = Covariance::Zero();
  for (Eigen::Index i = 0; i < jacobian.rows(); ++i) {
    middle += scale[static_cast<std::size_t>(i)] * jacobian.row(i).transpose() * jacobian.row(i);
  }
  std::vector<int> row(bins.size(), -1);  // bins' index → used bin's index
  for (std::size_t i = 0, k = 0; i < bins.size(); ++i) {
    if (bins[i].used) row[i] = static_cast<int>(k++);
  }
  const auto weight = [&](int used, int component) {
    const BinPoint& p = points[static_cast<std::size_t>(used)];
    return component == 0 ? p.wPhi : p.wTheta;
  };
  for (const BinCovariance& c : covariances) {
    if (c.binA < 0 || c.binB < 0 || static_cast<std::size_t>(c.binA) >= bins.size() ||
        static_cast<std::size_t>(c.binB) >= bins.size()) {
      return Error{fmt::format("a bin covariance names bin {} or {}, beyond the {} bins", c.binA, c.binB, bins.size())};
    }
    const int ua = row[static_cast<std::size_t>(c.binA)], ub = row[static_cast<std::size_t>(c.binB)];
    if (ua < 0 || ub < 0 || !std::isfinite(c.value)) continue;
    const int i = 2 * ua + c.componentA, j = 2 * ub + c.componentB;
    const double rho = c.value * weight(ua, c.componentA) * weight(ub, c.componentB);
    if (i == j) {
      middle += rho * jacobian.row(i).transpose() * jacobian.row(i);
    } else {
      const Covariance term = jacobian.row(i).transpose() * jacobian.row(j);
      middle += rho * (term + term.transpose());
    }
  }
  return middle;
}

// H⁻¹·middle·H⁻¹, symmetrised; an error when it is not a covariance.
Result<Covariance> sandwich(const Covariance& hInverse, const Covariance& middle) {
  Covariance c = hInverse * middle * hInverse;
  c = 0.5 * (c + c.transpose());
  if (!(c.diagonal().array() > 0.0).all() || !c.allFinite()) {
    return Error{"the covariance with the bins' correlations is not positive: the correlations are implausible"};
  }
  return c;
}

// The whitened Jacobian at the fit's minimum.
Result<Jacobian> jacobianAtMinimum(const FitResult& result, const std::vector<BinPoint>& points, const FitGeometry& g) {
  ceres::AutoDiffCostFunction<ProfileResiduals, ceres::DYNAMIC, kFitParams> cost(
      new ProfileResiduals{&points, g.radii, g.response}, static_cast<int>(2 * points.size()));
  auto jacobian = jacobianAt(cost, result.parameters.values);
  if (!jacobian) return Error{"the fit's Jacobian could not be evaluated"};
  return std::move(*jacobian);
}

}  // namespace

Status applyBinCovariances(FitResult& result, const std::vector<ProfileBin>& bins, const FitGeometry& g,
                           const std::vector<BinCovariance>& covariances) {
  if (covariances.empty()) return {};
  if (!result.covariance) return Error{"the fit's covariance is singular: no errors to correct"};
  const std::vector<BinPoint> points = pointsOf(bins, g);
  auto jacobian = jacobianAtMinimum(result, points, g);
  if (!jacobian) return jacobian.error();
  auto middle = sandwichMiddle(*jacobian, std::vector<double>(static_cast<std::size_t>(jacobian->rows()), 1.0), points,
                               bins, covariances);
  if (!middle) return middle.error();
  auto c = sandwich(*result.covariance, *middle);
  if (!c) return c.error();
  setCovariance(result, *c);
  setDerived(result, g.radii.r1);
  return {};
}

Status setStatisticalCovariance(FitResult& result, const std::vector<ProfileBin>& bins,
                                const std::vector<ProfileBin>& statistical, const FitGeometry& g,
                                const std::vector<BinCovariance>& covariances) {
  if (!result.covariance) return {};
  if (statistical.size() != bins.size()) {
    return Error{fmt::format("{} bins with their statistical errors for {} fitted", statistical.size(), bins.size())};
  }
  // R: the share of each residual's variance that the events make, σ_stat²/σ².
  std::vector<double> scale;
  for (std::size_t i = 0; i < bins.size(); ++i) {
    if (!bins[i].used) continue;
    for (const auto& [total, stat] : {std::pair{bins[i].sigmaPhi, statistical[i].sigmaPhi},
                                      std::pair{bins[i].sigmaTheta, statistical[i].sigmaTheta}}) {
      const double share = (stat * stat) / (total * total);
      if (!(share >= 0.0 && share <= 1.0 + 1e-9)) {
        return Error{fmt::format("profile bin ({}, {}): its statistical error {:.3g} exceeds its total {:.3g}",
                                 bins[i].iPhi, bins[i].iTheta, stat, total)};
      }
      scale.push_back(std::min(share, 1.0));
    }
  }
  const std::vector<BinPoint> points = pointsOf(bins, g);
  auto jacobian = jacobianAtMinimum(result, points, g);
  if (!jacobian) return jacobian.error();
  auto middle = sandwichMiddle(*jacobian, scale, points, bins, covariances);
  if (!middle) return middle.error();
  auto c = sandwich(*result.covariance, *middle);
  if (!c) return c.error();
  result.statisticalCovariance = *c;
  for (int k = 0; k < kFitParams; ++k) result.statisticalErrors[k] = std::sqrt((*c)(k, k));
  setDerived(result, g.radii.r1);
  return {};
}

namespace {

using ProfileCost = ceres::AutoDiffCostFunction<ProfileResiduals, ceres::DYNAMIC, kFitParams>;

// The used bins as points of the χ², each checked: the model places a bin's showers at
// R(E, θ), and outside the calorimeter it is meaningless (an energy of 1e-300 MeV, or a
// depth offset of metres). Fails also with fewer residuals than parameters.
Result<std::vector<BinPoint>> fitPoints(const std::vector<ProfileBin>& bins, const FitGeometry& g) {
  std::vector<BinPoint> points = pointsOf(bins, g);
  for (std::size_t i = 0, k = 0; i < bins.size(); ++i) {
    if (!bins[i].used) continue;
    const BinPoint& p = points[k++];
    if (!(p.radius > 0.0 && p.radius < 2.0 * g.radii.rp3) || !std::isfinite(p.phi) || !std::isfinite(p.theta)) {
      return Error{
          fmt::format("profile bin ({}, {}): the shower depth R(E, theta) = {:.4g} cm at its mean energy "
                      "{:.4g} MeV lies outside the calorimeter (0 to {:.4g} cm): not a plausible bin (energy "
                      "in MeV? depth offset in cm?)",
                      bins[i].iPhi, bins[i].iTheta, p.radius, bins[i].energyMean, 2.0 * g.radii.rp3)};
    }
  }
  if (2 * static_cast<int>(points.size()) <= kFitParams) {
    return Error{
        fmt::format("only {} {} at least 10 entries: the 12 parameters need at least 7 "
                    "(are there selected e+e- -> e+e- events at 45-135 deg?)",
                    counted(points.size(), "profile bin"), points.size() == 1 ? "has" : "have")};
  }
  return points;
}

// The staged minimisation of docs/contract.md §8: each stage frees its parameters and starts where the
// last ended. Fills the stages, parameters, χ², ndf, p-value and the status so far.
void minimiseInStages(ceres::Problem& problem, geometry::ParamVector& eta, const FitOptions& options,
                      FitResult& result) {
  std::vector<Param> free;
  bool allConverged = true;
  for (const auto& stage : options.stages) {
    free.insert(free.end(), stage.begin(), stage.end());
    std::vector<int> constant;
    for (Param p : kAllParams) {
      if (std::find(free.begin(), free.end(), p) == free.end()) constant.push_back(static_cast<int>(index(p)));
    }
    if (constant.empty()) {
      if (problem.HasManifold(eta.data())) problem.SetManifold(eta.data(), nullptr);
    } else {
      problem.SetManifold(eta.data(), new ceres::SubsetManifold(kFitParams, constant));
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = options.maxIterations;
    so.function_tolerance = 1e-14;
    so.gradient_tolerance = 1e-14;
    so.parameter_tolerance = 1e-14;
    so.logging_type = ceres::SILENT;
    so.num_threads = 1;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    StageResult sr;
    sr.free = free;
    sr.chi2 = 2.0 * summary.final_cost;
    sr.iterations = static_cast<int>(summary.iterations.size()) - 1;
    sr.converged = summary.termination_type == ceres::CONVERGENCE && std::isfinite(summary.final_cost) &&
                   summary.final_cost >= 0.0;
    // Ceres' message can hold a dump of every residual: its first line is what a user reads.
    sr.termination = summary.message.substr(0, summary.message.find('\n')).substr(0, 300);
    allConverged = allConverged && sr.converged;
    result.stages.push_back(sr);
  }

  result.parameters.values = eta;
  result.chi2 = result.stages.back().chi2;
  if (!(result.chi2 >= 0.0)) result.chi2 = std::numeric_limits<double>::quiet_NaN();  // never evaluated
  result.ndf = 2 * result.binsUsed - kFitParams;
  result.pValue =
      std::isfinite(result.chi2) ? chi2PValue(result.chi2, result.ndf) : std::numeric_limits<double>::quiet_NaN();
  result.status = allConverged ? FitStatus::Converged : FitStatus::NotConverged;
  for (std::size_t k = 0; k < result.stages.size(); ++k) {
    if (!result.stages[k].converged) {
      result.warnings.push_back(fmt::format("stage {} ({}) did not converge: {}", k + 1, paramList(options.stages[k]),
                                            result.stages[k].termination));
    }
  }
}

// The covariance (JᵀJ)⁻¹ of the whitened residuals at the minimum, through the correlation-
// scaled matrix D·JᵀJ·D (D = diag(JᵀJ)^(−1/2)), whose eigenvalues are unit-free: sets the
// eigenvalues, the weak direction, and either the covariance (with a warning when it is
// ill-conditioned) or the status CovarianceSingular. (The residuals always evaluate; were
// they not to, a zero Jacobian reads as singular.)
void analyseCovariance(const ProfileCost& cost, const FitOptions& options, FitResult& result) {
  const Jacobian jacobian =
      jacobianAt(cost, result.parameters.values).value_or(Jacobian::Zero(cost.num_residuals(), kFitParams));
  const Covariance jtj = jacobian.transpose() * jacobian;
  const Eigen::Matrix<double, kFitParams, 1> diag = jtj.diagonal();
  bool singular = (diag.array() <= 0.0).any();
  Covariance covariance = Covariance::Constant(std::numeric_limits<double>::quiet_NaN());
  if (!singular) {
    const Eigen::Matrix<double, kFitParams, 1> d = diag.array().rsqrt();
    const Covariance scaled = d.asDiagonal() * jtj * d.asDiagonal();
    Eigen::SelfAdjointEigenSolver<Covariance::Base> eig(scaled);
    const auto& ev = eig.eigenvalues();
    result.eigenvalues.assign(ev.data(), ev.data() + kFitParams);
    result.weakDirection = eig.eigenvectors().col(0);
    std::string combo;
    for (Param p : kAllParams) {
      const double w = result.weakDirection[p];
      if (std::abs(w) > 0.1) combo += fmt::format("{}{:+.2f}·{}", combo.empty() ? "" : " ", w, name(p));
    }
    result.weakCombination = combo;
    singular = ev[0] < options.singularEigenvalue * ev[kFitParams - 1];
    if (!singular) {
      const Covariance inverseScaled =
          eig.eigenvectors() * ev.cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
      covariance = d.asDiagonal() * inverseScaled * d.asDiagonal();
      if (ev[kFitParams - 1] / ev[0] > options.conditionWarning) {
        result.warnings.push_back(fmt::format(
            "the covariance is ill-conditioned (condition number {:.3g} of the correlation-scaled matrix); the weak "
            "combination is {}",
            ev[kFitParams - 1] / ev[0], combo));
      }
    }
  }
  if (!singular) {
    setCovariance(result, covariance);
    return;
  }
  result.status = FitStatus::CovarianceSingular;
  std::string evs;
  for (double e : result.eigenvalues) evs += fmt::format("{}{:.3g}", evs.empty() ? "" : ", ", e);
  result.warnings.push_back(fmt::format(
      "the covariance is singular: the data do not constrain {} (eigenvalues of the correlation-scaled JᵀJ: {}); "
      "no errors are given",
      result.weakCombination.empty() ? "some parameter" : result.weakCombination, evs));
}

// A converged fit whose p-value is below kPoorFitPValue is a poor fit; negative gaps and
// bins left out are said: what a calibration physicist acts on.
void judge(const std::vector<ProfileBin>& bins, FitResult& result) {
  if (result.status == FitStatus::Converged && result.pValue < kPoorFitPValue) {
    result.status = FitStatus::PoorFit;
    result.warnings.push_back(fmt::format(
        "chi2/ndf = {:.1f}/{} (p-value {:.2g}): the model does not describe the profiles (a detector or "
        "reconstruction effect the model lacks, repeated events, or errors too small); use the result with care",
        result.chi2, result.ndf, result.pValue));
  }
  for (std::string& w : geometry::warnings(result.parameters, &result.errors)) result.warnings.push_back(std::move(w));
  if (!result.binsLeftOut.empty()) {
    std::string list;
    for (const auto& [i, j] : result.binsLeftOut) list += fmt::format("{}({},{})", list.empty() ? "" : " ", i, j);
    result.warnings.push_back(fmt::format("{} of {} {} {} fewer than 10 entries and {} left out: {}",
                                          result.binsLeftOut.size(), bins.size(), nounFor(bins.size(), "profile bin"),
                                          result.binsLeftOut.size() == 1 ? "has" : "have",
                                          result.binsLeftOut.size() == 1 ? "is" : "are", list));
  }
}

}  // namespace

Result<FitResult> fitProfiles(const std::vector<ProfileBin>& bins, const FitGeometry& g, const FitOptions& options) {
  if (Status s = options.validate(); !s) return s.error();
  auto points = fitPoints(bins, g);
  if (!points) return points.error();
  FitResult result;
  for (const auto& b : bins) {
    if (!b.used) result.binsLeftOut.emplace_back(b.iPhi, b.iTheta);
  }
  result.binsUsed = static_cast<int>(points->size());

  geometry::ParamVector eta = geometry::ParamVector::Zero();
  auto* cost = new ProfileCost(new ProfileResiduals{&*points, g.radii, g.response}, 2 * result.binsUsed);
  ceres::Problem problem;  // owns `cost`
  problem.AddResidualBlock(cost, nullptr, eta.data());
  minimiseInStages(problem, eta, options, result);
  analyseCovariance(*cost, options, result);
  setDerived(result, g.radii.r1);
  judge(bins, result);
  return result;
}

}  // namespace emcalign::calib
