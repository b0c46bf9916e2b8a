// The derivation of the model corrections (validation/derive_corrections.hpp): its three
// samples, the depth, the parting plane, the nominal profile, the response and the closure.

#include "emcalign/validation/derive_corrections.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>

#include <fmt/format.h>
#include <Eigen/Cholesky>

#include "derive_corrections_internal.hpp"
#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/residual_model.hpp"
#include "emcalign/validation/campaign.hpp"

namespace emcalign::validation {

using derivation::firstStage;
using derivation::fitResponseSample;
using derivation::lastStage;
using derivation::Sample;
using derivation::simulateSample;
using geometry::AlignmentParameters;
using io::Json;

PlusWeightTerms plusWeightTerms(const calib::ProfileBin& sample, const calib::ProfileBin& nominal,
                                const AlignmentParameters& truth, const geometry::ShowerDepth& depth,
                                const geometry::AlignmentRadii& radii) {
  const auto plus = geometry::hemisphereTransform<double>(truth.values, geometry::Hemisphere::Plus, radii);
  const auto minus = geometry::hemisphereTransform<double>(truth.values, geometry::Hemisphere::Minus, radii);
  const double radius = depth.radius(sample.energyMean, sample.thetaMean);
  const auto fp = geometry::mixedModelResidual<double>(plus, minus, sample.phiMean, sample.thetaMean, radius, 1.0);
  const auto fm = geometry::mixedModelResidual<double>(plus, minus, sample.phiMean, sample.thetaMean, radius, 0.0);
  const double vPhi = 1.0 / (sample.sigmaPhi * sample.sigmaPhi + nominal.sigmaPhi * nominal.sigmaPhi);
  const double vTheta = 1.0 / (sample.sigmaTheta * sample.sigmaTheta + nominal.sigmaTheta * nominal.sigmaTheta);
  const double dPhi = fp.phi - fm.phi, dTheta = fp.theta - fm.theta;
  return {(sample.yPhi - nominal.yPhi - fm.phi) * dPhi * vPhi +
              (sample.yTheta - nominal.yTheta - fm.theta) * dTheta * vTheta,
          dPhi * dPhi * vPhi + dTheta * dTheta * vTheta};
}

namespace {

// One simulated sample of a derivation: its placement, seed, size and name (progress, errors).
struct SampleRun {
  const AlignmentParameters& truth;
  std::uint64_t seed;
  std::int64_t events;
  std::string_view stage;
};

// Simulates the sample with the derivation's settings into the filler (selection, profiles);
// fails when none is selected.
Status simulateInto(const geometry::Calorimeter& calo, const DerivationOptions& o, const SampleRun& sample,
                    calib::ProfileFiller& filler, const DerivationProgress& progress) {
  sim::SimulationOptions so = o.simulation;
  so.seed = sample.seed;
  auto simulation = sim::Simulation::create(calo, sample.truth, so);
  if (!simulation) return simulation.error();
  Status run = simulation->run(
      sample.events, o.threads,
      [&](std::span<const ParticleRow> rows, std::span<const TruthRow>, std::span<const Hit>) {
        filler.addEvents(rows);
        return Status{};
      },
      [&](std::int64_t done) {
        if (progress) progress(sample.stage, done, sample.events);
      });
  if (!run) return run;
  if (Status sel = filler.checkSelected(); !sel) {
    return Error{fmt::format("{}: {}", sample.stage, sel.error().message)};
  }
  return {};
}

std::vector<calib::ProfileBin> profileOf(const Sample& s, const geometry::ShowerDepth& depth,
                                         calib::ProfileOptions po) {
  calib::Profiles profiles(std::move(po));
  for (const auto& row : s.particles) {
    if (const auto y = calib::residualOf(row, depth)) profiles.fill(*y);
  }
  return profiles.bins();
}

// χ²(δ) of the shift sample against the model, the nominal sample subtracted bin by bin.
struct DepthChi2 {
  const Sample* shifted;
  const Sample* nominal;
  calib::FitGeometry geometry;
  int bins = 0;

  double operator()(double offset) {
    geometry::ShowerDepth depth = geometry.depth;
    depth.offset = offset;
    calib::ProfileOptions po;
    po.sigmaSys = 0.0;
    const auto s = profileOf(*shifted, depth, po), n = profileOf(*nominal, depth, po);
    calib::FitGeometry g = geometry;
    g.depth = depth;
    double chi2 = 0.0;
    bins = 0;
    for (std::size_t b = 0; b < s.size(); ++b) {
      if (!s[b].used || !n[b].used) continue;
      const auto f = calib::modelAt(g, shifted->truth.values, s[b].phiMean, s[b].thetaMean, s[b].energyMean);
      const double rPhi = s[b].yPhi - n[b].yPhi - f.phi, rTheta = s[b].yTheta - n[b].yTheta - f.theta;
      chi2 += rPhi * rPhi / (s[b].sigmaPhi * s[b].sigmaPhi + n[b].sigmaPhi * n[b].sigmaPhi) +
              rTheta * rTheta / (s[b].sigmaTheta * s[b].sigmaTheta + n[b].sigmaTheta * n[b].sigmaTheta);
      ++bins;
    }
    return chi2;
  }
};

// W₊ per φ column from a gap sample: the least-squares W₊ of Δy = f₋ + W₊·(f₊ − f₋) over
// the column's bins (Δy = gap sample − nominal sample, statistical σ), both components.
struct ColumnWeights {
  std::vector<double> measured, errors;  // every column, as measured
  std::vector<double> weights;           // clamped to [0, 1] next to the plane, hard elsewhere
};

Status measureColumnWeights(const std::vector<calib::ProfileBin>& gb, const std::vector<calib::ProfileBin>& nb,
                            const AlignmentParameters& gap, const geometry::ShowerDepth& depth,
                            const geometry::AlignmentRadii& radii, ColumnWeights& out) {
  const int columns = calib::kProfilePhiBins;
  out.measured.assign(static_cast<std::size_t>(columns), std::nan(""));
  out.errors.assign(static_cast<std::size_t>(columns), std::nan(""));
  out.weights.assign(static_cast<std::size_t>(columns), 0.0);
  for (int c = 0; c < columns; ++c) {
    double num = 0.0, den = 0.0;
    for (std::size_t b = 0; b < gb.size(); ++b) {
      if (gb[b].iPhi != c || !gb[b].used || !nb[b].used) continue;
      const PlusWeightTerms t = plusWeightTerms(gb[b], nb[b], gap, depth, radii);
      num += t.num;
      den += t.den;
    }
    if (!(den > 0.0))
      return Error{fmt::format("parting-plane response: phi column {} has no usable bins (more --events?)", c)};
    const auto k = static_cast<std::size_t>(c);
    out.measured[k] = num / den;
    out.errors[k] = 1.0 / std::sqrt(den);
    out.weights[k] = calib::PartingPlaneResponse::nextToPlane(c, columns)
                         ? std::clamp(num / den, 0.0, 1.0)
                         : calib::PartingPlaneResponse::hardWeight(c, columns);
  }
  return {};
}

// Golden-section search for the minimum of a unimodal function on [a, b].
template <typename F>
double goldenMinimum(F&& f, double a, double b, double tolerance) {
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  double c = b - g * (b - a), d = a + g * (b - a);
  double fc = f(c), fd = f(d);
  while (b - a > tolerance) {
    if (fc < fd) {
      b = d;
      d = c;
      fd = fc;
      c = b - g * (b - a);
      fc = f(c);
    } else {
      a = c;
      c = d;
      fc = fd;
      d = a + g * (b - a);
      fd = f(d);
    }
  }
  return 0.5 * (a + b);
}

}  // namespace

namespace derivation {

AlignmentParameters sampleTruth(const DerivationOptions& o, int k) {
  AlignmentParameters t;
  if (k == 1) t[Param::Dx] = t[Param::Dy] = t[Param::Dz] = o.shift;
  if (k == 2) t[Param::Dp1] = t[Param::Dp2] = t[Param::Dp3] = 2.0 * o.gap;
  return t;
}

Result<Sample> simulateSample(const geometry::Calorimeter& calo, const DerivationOptions& o, int k,
                              const DerivationProgress& progress) {
  Sample s;
  s.truth = sampleTruth(o, k);
  // The residuals at the nominal depth only decide which tracks reach the EMC; the rows are
  // kept and their residuals rebuilt at every depth tried.
  calib::ProfileFiller filler(
      geometry::ShowerDepth::of(calo.description()), calib::SelectionOptions{}, {},
      [&](const ParticleRow& row, const calib::ParticleResidual&) { s.particles.push_back(row); });
  const std::uint64_t seed = Rng(o.seed ^ 0xC0EEC7ULL, static_cast<std::uint64_t>(k)).next();
  const std::string stage = fmt::format("simulate {}", kSampleNames[k]);
  const SampleRun run{.truth = s.truth, .seed = seed, .events = o.events, .stage = stage};
  if (Status st = simulateInto(calo, o, run, filler, progress); !st) return st.error();
  s.selectedEvents = filler.fill().cutFlow.events.back();
  return s;
}

ResponseDraw responseDraw(const geometry::Calorimeter& calo, const DerivationOptions& o, int i) {
  Rng rng(o.seed ^ 0x2E5905EULL, static_cast<std::uint64_t>(i));
  ResponseDraw d;
  d.truth = drawTruth(o.responseRanges, calo.description().r1(), rng);
  d.seed = rng.next();
  return d;
}

// Response sample i simulated and fitted with the first stage's corrections (statistical
// errors): the fitted parameters.
Result<geometry::ParamVector> fitResponseSample(const geometry::Calorimeter& calo, const DerivationOptions& o,
                                                const calib::ModelCorrections& firstStage, int i,
                                                const DerivationProgress& progress) {
  calib::FitGeometry g = calib::FitGeometry::of(calo.description());
  g.apply(firstStage);
  calib::ProfileOptions po;
  po.partingPlane = firstStage.partingPlane;
  po.nominalProfile = firstStage.nominalProfile;
  const std::string stage = fmt::format("simulate response sample {}", i);
  const ResponseDraw draw = responseDraw(calo, o, i);
  calib::ProfileFiller filler(g.depth, calib::SelectionOptions{}, po);
  const SampleRun run{.truth = draw.truth, .seed = draw.seed, .events = o.responseEvents, .stage = stage};
  if (Status st = simulateInto(calo, o, run, filler, progress); !st) {
    return st.error();
  }
  auto fit = calib::fitProfiles(filler.fill().profiles.bins(0.0), g);
  if (!fit) return Error{fmt::format("{}: {}", stage, fit.error().message)};
  if (!usable(fit->status)) {
    return Error{fmt::format("{}: the fit's status is '{}'", stage, emcalign::name(fit->status))};
  }
  return fit->parameters.values;
}

}  // namespace derivation

namespace {

using derivation::responseDraw;

// The response over the validation ranges: η̂ of the response samples regressed on their η
// with a constant (calib/corrections.hpp, 4.), into the report with its errors.
Status regressResponse(const geometry::Calorimeter& calo, const DerivationOptions& o,
                       const std::vector<geometry::ParamVector>& fitted, DerivationReport& report) {
  const int n = o.responseSamples;
  constexpr int kCols = 2 * static_cast<int>(kNumParams) + 1;  // 1, η, η·dx_rel
  Eigen::MatrixXd x(n, kCols), y(n, static_cast<int>(kNumParams));
  for (int i = 0; i < n; ++i) {
    const AlignmentParameters truth = responseDraw(calo, o, i).truth;
    const double dxRel = (truth[Param::Dp1] + truth[Param::Dp2] + truth[Param::Dp3]) / 6.0;
    x(i, 0) = 1.0;
    x.row(i).segment(1, kNumParams) = truth.values.transpose();
    x.row(i).tail(kNumParams) = dxRel * truth.values.transpose();
    y.row(i) = fitted[static_cast<std::size_t>(i)].transpose();
  }
  // Least squares: y = x·B, B = (xᵀx)⁻¹xᵀy; row 0 of B is c, then Rᵀ, then Gᵀ. Errors from
  // the residual scatter of each fitted parameter.
  const Eigen::MatrixXd xtx = x.transpose() * x;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(xtx);
  const Eigen::MatrixXd b = ldlt.solve(x.transpose() * y);
  const Eigen::MatrixXd inverse = ldlt.solve(Eigen::MatrixXd::Identity(kCols, kCols));
  const Eigen::MatrixXd residual = y - x * b;
  calib::FitResponse response;
  for (int j = 0; j < static_cast<int>(kNumParams); ++j) {
    const double variance = residual.col(j).squaredNorm() / (n - kCols);
    response.offset[j] = b(0, j);
    report.responseOffsetErrors[j] = std::sqrt(variance * inverse(0, 0));
    // The error of the response's prediction, averaged over the samples' truths (the mean
    // leverage of a least-squares fit with kCols coefficients is kCols/n): what it adds,
    // common to every fit using the file, for a truth inside the ranges.
    report.responseParameterErrors[j] = std::sqrt(variance * kCols / n);
    for (int k = 0; k < static_cast<int>(kNumParams); ++k) {
      response.matrix(j, k) = b(k + 1, j);
      response.gapMatrix(j, k) = b(k + 1 + static_cast<int>(kNumParams), j);
      report.responseErrors(j, k) = std::sqrt(variance * inverse(k + 1, k + 1));
    }
  }
  if (Status s = response.validate(); !s) {
    return Error{
        fmt::format("the measured response: {} (too few response events for {} coefficients per parameter? "
                    "more --response-samples or --response-events)",
                    s.error().message, kCols)};
  }
  report.corrections.response = std::make_shared<const calib::FitResponse>(response);
  return {};
}

}  // namespace

Status DerivationOptions::validate() const {
  if (responseSamples != 0 && responseSamples < 50) return Error{"--response-samples must be 0 or at least 50"};
  if (responseSamples != 0 && responseEvents < 1000) return Error{"--response-events must be at least 1000"};
  if (events < 1000) return Error{"--events must be at least 1000 per sample"};
  if (!(shift > 0.0) || !(gap > 0.0)) return Error{"--shift and --gap must be positive"};
  if (!(depthLow < depthHigh)) return Error{"the depth search interval is empty"};
  // The simulation's settings as its samples check them (the counters: where the detector is known).
  if (Status s = simulation.generator.validate(); !s) return s;
  if (Status s = simulation.tracking.validate(); !s) return s;
  if (Status s = simulation.reconstruction.validate(); !s) return s;
  return {};
}

namespace {

// The depth offset's search: the golden-section tolerance, the step of the χ² curvature
// that gives its error, and how close to the interval's ends a minimum is refused (cm).
constexpr double kDepthTolerance = 0.005, kDepthCurvatureStep = 0.25, kDepthEdgeMargin = 0.05;

// Step 1, the depth: the offset δ whose R(E, θ) + δ makes the shift sample's profile minus
// the nominal one the model of the known shift (DepthChi2), with its error from the χ²'s
// curvature.
Status deriveDepth(const Sample& shifted, const Sample& nominal, const calib::FitGeometry& nominalGeometry,
                   const DerivationOptions& o, DerivationReport& report) {
  DepthChi2 chi2{&shifted, &nominal, nominalGeometry};
  const double delta = goldenMinimum(chi2, o.depthLow, o.depthHigh, kDepthTolerance);
  const double h = kDepthCurvatureStep;
  const double c0 = chi2(delta), cp = chi2(delta + h), cm = chi2(delta - h);
  report.depthChi2 = c0;
  report.depthBins = chi2.bins;
  const double curvature = (cp - 2.0 * c0 + cm) / (h * h);
  report.depthOffsetError = curvature > 0.0 ? std::sqrt(2.0 / curvature) : std::nan("");
  if (delta - o.depthLow < kDepthEdgeMargin || o.depthHigh - delta < kDepthEdgeMargin) {
    return Error{fmt::format("the depth offset sits at the edge of the search interval [{}, {}] cm: {:.2f} cm",
                             o.depthLow, o.depthHigh, delta)};
  }
  report.corrections.depthOffset = delta;
  report.corrections.beamEnergy = o.simulation.generator.beamEnergy;
  return {};
}

// Step 2, the parting-plane response at the derived depth: per φ column next to the plane,
// the least-squares W₊ of Δy = f₋ + W₊·(f₊ − f₋) over the column's bins (Δy = gap sample −
// nominal sample, statistical σ), both components.
Status derivePartingPlane(const std::vector<calib::ProfileBin>& gappedBins,
                          const std::vector<calib::ProfileBin>& nominalBins, const AlignmentParameters& gap,
                          const geometry::ShowerDepth& depth, const geometry::AlignmentRadii& radii,
                          DerivationReport& report) {
  ColumnWeights largest;
  if (Status s = measureColumnWeights(gappedBins, nominalBins, gap, depth, radii, largest); !s) return s.error();
  report.columnWeights = largest.measured;
  report.columnWeightErrors = largest.errors;
  auto response = calib::PartingPlaneResponse::create(largest.weights);
  if (!response) return response.error();
  report.corrections.partingPlane = std::make_shared<const calib::PartingPlaneResponse>(std::move(*response));
  return {};
}

// Step 3, the nominal sample's profile at the derived depth, to be subtracted from every bin
// (NaN where the bin had too few entries).
Result<calib::NominalProfile> nominalProfileOf(const std::vector<calib::ProfileBin>& nominalBins,
                                               const calib::ProfileOptions& po) {
  calib::NominalProfile t;
  t.phiBins = po.phiBins;
  t.thetaBins = po.thetaBins;
  const double nan = std::nan("");
  for (const auto& b : nominalBins) {
    t.yPhi.push_back(b.used ? b.yPhi : nan);
    t.yTheta.push_back(b.used ? b.yTheta : nan);
    t.sigmaPhi.push_back(b.used ? b.sigmaPhi : nan);
    t.sigmaTheta.push_back(b.used ? b.sigmaTheta : nan);
  }
  if (Status st = t.validate(); !st) return st.error();
  return t;
}

// The closure: the shift and gap samples fitted with the paper's model and with all the
// corrections, as data would be fitted; each reports the quantity its sample moved (dx,
// dx_rel).
Status closureFits(const Sample& shifted, const Sample& gapped, const calib::FitGeometry& nominalGeometry,
                   const DerivationOptions& o, DerivationReport& report) {
  auto fitOne = [&](const Sample& s, bool corrected) -> Result<calib::FitResult> {
    calib::FitGeometry g = nominalGeometry;
    calib::ProfileOptions po;
    if (corrected) {
      g.apply(report.corrections);
      po.partingPlane = report.corrections.partingPlane;
      po.nominalProfile = report.corrections.nominalProfile;
    }
    return calib::fitProfiles(profileOf(s, g.depth, po), g);
  };
  struct Closure {
    const Sample* sample;
    const char* name;
    Physical measured;
    double truth;
  };
  for (const Closure& k :
       {Closure{&shifted, "shift", Physical::Dx, o.shift}, Closure{&gapped, "gap", Physical::DxRel, o.gap}}) {
    auto paper = fitOne(*k.sample, false);
    if (!paper) return paper.error();
    auto corrected = fitOne(*k.sample, true);
    if (!corrected) return corrected.error();
    ClosureFit c;
    c.sample = k.name;
    c.parameter = std::string(name(k.measured));
    c.truth = k.truth;
    c.paperModel = paper->derived[k.measured].value;
    c.paperError = paper->derived[k.measured].error;
    c.corrected = corrected->derived[k.measured].value;
    c.correctedError = corrected->derived[k.measured].error;
    report.closure.push_back(c);
  }
  return {};
}

}  // namespace

namespace derivation {

// The depth, the parting plane and the nominal profile from the three samples (N, S, G).
Result<DerivationReport> firstStage(const calib::FitGeometry& nominalGeometry, const DerivationOptions& o,
                                    const std::vector<Sample>& samples) {
  const Sample &nominal = samples[0], &shifted = samples[1], &gapped = samples[2];
  DerivationReport report;
  for (int k = 0; k < 3; ++k) report.selectedEvents[k] = samples[static_cast<std::size_t>(k)].selectedEvents;
  if (Status s = deriveDepth(shifted, nominal, nominalGeometry, o, report); !s) return s.error();

  geometry::ShowerDepth depth = nominalGeometry.depth;
  depth.offset = report.corrections.depthOffset;
  calib::ProfileOptions po;
  po.sigmaSys = 0.0;
  const auto gb = profileOf(gapped, depth, po), nb = profileOf(nominal, depth, po);
  if (Status s = derivePartingPlane(gb, nb, gapped.truth, depth, nominalGeometry.radii, report); !s) return s.error();

  auto nominalProfile = nominalProfileOf(nb, po);
  if (!nominalProfile) return nominalProfile.error();
  report.corrections.nominalProfile = std::make_shared<const calib::NominalProfile>(std::move(*nominalProfile));
  return report;
}

// The rest, with the first stage in `report`: the response from the response samples' fitted
// parameters, the errors of the nominal profile, the closure fits.
Status lastStage(const geometry::Calorimeter& calo, const calib::FitGeometry& nominalGeometry,
                 const DerivationOptions& o, const std::vector<Sample>& samples,
                 const std::vector<geometry::ParamVector>& responseFits, DerivationReport& report,
                 const DerivationProgress& progress) {
  if (o.responseSamples > 0) {
    if (Status s = regressResponse(calo, o, responseFits, report); !s) return s;
  }
  // The nominal profile's statistical noise is common to every fit that uses the file: the
  // errors of a fit to it alone (statistical σ), with the model the file makes, are that
  // systematic error, per parameter.
  calib::FitGeometry corrected = nominalGeometry;
  corrected.apply(report.corrections);
  calib::ProfileOptions po;
  po.sigmaSys = 0.0;
  geometry::ShowerDepth depth = nominalGeometry.depth;
  depth.offset = report.corrections.depthOffset;
  auto noise = calib::fitProfiles(profileOf(samples[0], depth, po), corrected);
  if (!noise) return Error{fmt::format("fit of the nominal profile: {}", noise.error().message)};
  report.nominalProfileErrors = noise->errors;

  if (progress) progress("closure fits", 0, 1);
  if (Status s = closureFits(samples[1], samples[2], nominalGeometry, o, report); !s) return s;
  if (progress) progress("closure fits", 1, 1);
  return {};
}

}  // namespace derivation

Result<DerivationReport> deriveCorrections(const geometry::Calorimeter& calo, const DerivationOptions& o,
                                           const DerivationProgress& progress) {
  if (Status s = o.validate(); !s) return s.error();
  const calib::FitGeometry nominalGeometry = calib::FitGeometry::of(calo.description());
  std::vector<Sample> samples;
  for (int k = 0; k < 3; ++k) {
    auto sample = simulateSample(calo, o, k, progress);
    if (!sample) return sample.error();
    samples.push_back(std::move(*sample));
  }
  if (progress) progress("depth", 0, 1);
  auto report = firstStage(nominalGeometry, o, samples);
  if (!report) return report.error();
  if (progress) progress("depth", 1, 1);
  std::vector<geometry::ParamVector> responseFits;
  for (int i = 0; i < o.responseSamples; ++i) {
    auto fitted = fitResponseSample(calo, o, report->corrections, i, progress);
    if (!fitted) return fitted.error();
    responseFits.push_back(*fitted);
  }
  if (Status s = lastStage(calo, nominalGeometry, o, samples, responseFits, *report, progress); !s) return s.error();
  return report;
}

}  // namespace emcalign::validation
