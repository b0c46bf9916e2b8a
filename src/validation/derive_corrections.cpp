#include "emcalign/validation/derive_corrections.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <set>
#include <stdexcept>

#include <fmt/format.h>
#include <Eigen/Cholesky>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/residual_model.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/io/strict_json.hpp"
#include "emcalign/validation/campaign.hpp"

namespace emcalign::validation {

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

// The selected particles of one derivation sample, kept so that the residuals can be
// rebuilt at any depth.
struct Sample {
  AlignmentParameters truth;
  std::vector<ParticleRow> particles;
  std::int64_t selectedEvents = 0;
};

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

// The three samples (N, S, G): their names (progress, the fan-out's files) and placements.
constexpr std::string_view kSampleNames[3] = {"nominal", "shift", "gap"};

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

namespace {

// Response sample i: its truth drawn over the validation ranges as `emcalign validate` draws
// them (then the simulation's seed from the same stream).
struct ResponseDraw {
  AlignmentParameters truth;
  std::uint64_t seed = 0;
};
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

namespace {

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

}  // namespace

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

namespace {

Json parameterErrorsJson(const geometry::ParamVector& errors) {
  Json out = Json::object();
  for (Param p : kAllParams) {
    out[std::string(name(p))] = errors[p] / AlignmentParameters::fileUnit(p);
  }
  return out;
}

// The statistical errors of R in file units (as the file's "response" matrix).
Json responseErrorJson(const DerivationReport& r) {
  Json rows = Json::array();
  for (Param pj : kAllParams) {
    Json row = Json::array();
    for (Param pk : kAllParams) {
      row.push_back(r.responseErrors(pj, pk) * AlignmentParameters::fileUnit(pk) / AlignmentParameters::fileUnit(pj));
    }
    rows.push_back(row);
  }
  Json offset = Json::array();
  for (Param p : kAllParams) {
    offset.push_back(r.responseOffsetErrors[p] / AlignmentParameters::fileUnit(p));
  }
  return {{"matrix", rows}, {"offset", offset}};
}

}  // namespace

DerivationProgress simulatedEventsProgress(std::function<void(std::int64_t)> events) {
  struct Count {
    std::int64_t before = 0, lastTotal = 0;  // events of the finished stages; the current one's total
    std::string lastStage;
  };
  return [count = std::make_shared<Count>(), events = std::move(events)](std::string_view stage, std::int64_t done,
                                                                         std::int64_t total) {
    if (stage.rfind("simulate", 0) != 0) return;
    if (stage != count->lastStage) {
      count->lastStage = std::string(stage);
      count->before += count->lastTotal;
      count->lastTotal = total;
    }
    events(count->before + done);
  };
}

Json derivationJson(const DerivationReport& r, const Json& settings) {
  calib::ModelCorrections c = r.corrections;
  Json closure = Json::array();
  for (const auto& f : r.closure) {
    closure.push_back({{"sample", f.sample},
                       {"parameter", f.parameter},
                       {"truth_cm", f.truth},
                       {"paper_model_cm", f.paperModel},
                       {"paper_model_error_cm", f.paperError},
                       {"corrected_cm", f.corrected},
                       {"corrected_error_cm", f.correctedError}});
  }
  const Json nominalErrors = parameterErrorsJson(r.nominalProfileErrors);
  c.derivedFrom = {{"command", "emcalign derive-corrections"},
                   {"settings", settings},
                   {"selected_events",
                    {{"nominal", r.selectedEvents[0]}, {"shift", r.selectedEvents[1]}, {"gap", r.selectedEvents[2]}}},
                   {"depth_offset_error_cm", r.depthOffsetError},
                   {"depth_chi2", r.depthChi2},
                   {"depth_bins", r.depthBins},
                   {"column_plus_weight_measured", r.columnWeights},
                   {"column_plus_weight_error", r.columnWeightErrors},
                   {"closure", closure},
                   {"response_error", r.corrections.response ? responseErrorJson(r) : Json(nullptr)},
                   {"response_parameter_errors",
                    r.corrections.response ? parameterErrorsJson(r.responseParameterErrors) : Json(nullptr)},
                   {"nominal_profile_parameter_errors", nominalErrors}};
  return calib::correctionsJson(c);
}

bool derivedWith(const std::string& file, const Json& settings) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) return false;
  // This command's own output of an earlier run: unreadable or other settings, derived again.
  auto text = io::readOwnOutput(file);
  auto j = text ? io::parseJson(*text, file) : Result<Json>(text.error());
  auto c = j ? calib::parseCorrections(*j, file) : Result<calib::ModelCorrections>(j.error());
  return c && c->derivedFrom.is_object() && c->derivedFrom.value("settings", Json()) == settings;
}

Result<std::vector<GridPoint>> planGrid(const std::string& dir, const std::vector<double>& energies,
                                        const std::function<Json(double beamEnergy)>& settingsAt) {
  namespace fs = std::filesystem;
  std::vector<GridPoint> points;
  std::set<std::string> names;
  for (double e : energies) {
    GridPoint p{e, (fs::path(dir) / calib::gridPointName(e)).string(), false};
    std::error_code ec;
    p.done = derivedWith(p.file, settingsAt(e));
    names.insert(fs::path(p.file).filename().string());
    points.push_back(std::move(p));
  }
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return points;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() == ".json" && !names.contains(name)) {
      return Error{
          fmt::format("{}: this grid directory holds {}, which is not one of the energies asked for: the "
                      "directory is the grid that fit --corrections reads (give its energy too, or remove "
                      "the file)",
                      dir, name)};
    }
  }
  if (ec) return Error{fmt::format("{}: cannot list the directory: {}", dir, ec.message())};
  return points;
}

std::string derivationTaskDirectory(const std::string& workDirectory, double beamEnergy) {
  return (std::filesystem::path(workDirectory) /
          ("derive-" + std::filesystem::path(calib::gridPointName(beamEnergy)).stem().string()))
      .string();
}

namespace {

namespace fs = std::filesystem;

// ------------------------------------------------------------------ the fan-out's files
// Each holds the point's settings (derived_from.settings of the corrections file): a file of
// other settings (an earlier plan at the same path) is done again by a task, refused by the
// merge. Every number is written as JSON's shortest exact form or as HDF5 doubles, so the
// merge computes what one process computes.

constexpr std::string_view kResponseFormat = "emcalign-derive-response/1";

std::string sampleFile(const std::string& dir, int k) {
  return (fs::path(dir) / fmt::format("{}.h5", kSampleNames[k])).string();
}
std::string firstStageFile(const std::string& dir) { return (fs::path(dir) / "first-stage.json").string(); }
std::string responseFile(const std::string& dir, const SampleBlock& b) {
  return (fs::path(dir) / fmt::format("response-{}-{}.json", b.first, b.last)).string();
}

Status writeSample(const std::string& file, int k, const Sample& s, const Json& settings) {
  io::WriterOptions wo;
  wo.attributes = {{"derivation_sample", std::string(kSampleNames[k])},
                   {"selected_events", std::to_string(s.selectedEvents)},
                   {"settings", settings.dump()}};
  wo.placement = io::Placement::InDirectory;
  auto writer = io::EventWriter::open(file, wo);
  if (!writer) return writer.error();
  if (Status st = (*writer)->append(s.particles, {}); !st) return st;
  return (*writer)->close();
}

// The sample in `file` if it holds sample k of `settings`; nullopt if it holds another.
Result<std::optional<Sample>> readSample(const std::string& file, const DerivationOptions& o, int k,
                                         const Json& settings) {
  io::ReaderOptions ro;
  ro.truth = false;
  ro.hits = false;
  auto reader = io::EventReader::open({file}, ro);
  if (!reader) return reader.error();
  std::map<std::string, std::string> attributes((*reader)->attributes().begin(), (*reader)->attributes().end());
  if (attributes["derivation_sample"] != kSampleNames[k] || attributes["settings"] != settings.dump()) {
    return std::optional<Sample>();
  }
  Sample s;
  s.truth = sampleTruth(o, k);
  try {
    std::size_t used = 0;
    s.selectedEvents = std::stoll(attributes["selected_events"], &used);
    if (used != attributes["selected_events"].size()) throw std::invalid_argument("trailing text");
  } catch (const std::exception&) {
    return Error{fmt::format("{}: attribute 'selected_events': expected an integer, got '{}'", file,
                             attributes["selected_events"])};
  }
  std::vector<ParticleRow> block;
  for (;;) {
    auto more = (*reader)->next(block);
    if (!more) return more.error();
    if (!*more) break;
    s.particles.insert(s.particles.end(), block.begin(), block.end());
  }
  return std::optional<Sample>(std::move(s));
}

double numberOrNan(const Json& j) { return j.is_null() ? std::nan("") : j.get<double>(); }

// The first stage in `file` (a corrections file with the report so far under derived_from)
// if it holds `settings`; nullopt if it holds others.
Result<std::optional<DerivationReport>> readFirstStage(const std::string& file, const Json& settings) {
  auto text = io::readOwnOutput(file);
  if (!text) return text.error();
  auto j = io::parseJson(*text, file);
  if (!j) return j.error();
  auto c = calib::parseCorrections(*j, file);
  if (!c) return c.error();
  if (!c->derivedFrom.is_object() || c->derivedFrom.value("settings", Json()) != settings) {
    return std::optional<DerivationReport>();
  }
  return io::strict::guarded([&] {
    const io::strict::StrictObject from(c->derivedFrom, "derived_from", file);
    DerivationReport r;
    r.corrections = *c;
    r.corrections.derivedFrom = Json();
    r.depthOffsetError = numberOrNan(from.at("depth_offset_error_cm")) * units::cm;
    r.depthChi2 = from.number("depth_chi2");
    r.depthBins = from.at("depth_bins").get<int>();
    r.columnWeights = from.at("column_plus_weight_measured").get<std::vector<double>>();
    r.columnWeightErrors = from.at("column_plus_weight_error").get<std::vector<double>>();
    const io::strict::StrictObject selected = from.object("selected_events");
    for (int k = 0; k < 3; ++k) r.selectedEvents[k] = selected.at(kSampleNames[k]).get<std::int64_t>();
    return std::optional<DerivationReport>(std::move(r));
  });
}

// The fitted parameters of the response samples in `file`, by sample, if it holds `settings`.
Result<std::map<int, geometry::ParamVector>> readResponseFile(const std::string& file, const Json& settings) {
  auto text = io::readOwnOutput(file);
  if (!text) return text.error();
  auto j = io::parseJson(*text, file);
  if (!j) return j.error();
  return io::strict::guarded([&] {
    const io::strict::StrictObject top(*j, "", file);
    top.allowOnly({"format", "settings", "samples"});
    if (top.string("format") != kResponseFormat) top.fail("format", fmt::format("expected '{}'", kResponseFormat));
    std::map<int, geometry::ParamVector> fits;
    if (top.at("settings") != settings) return fits;
    const Json& samples = top.at("samples");
    if (!samples.is_array()) top.fail("samples", "expected an array");
    for (std::size_t n = 0; n < samples.size(); ++n) {
      const io::strict::StrictObject one(samples[n], fmt::format("samples[{}]", n), file);
      one.allowOnly({"sample", "truth", "fitted"});
      const Json& fitted = one.at("fitted");
      if (!fitted.is_array() || fitted.size() != kNumParams) one.fail(one.pathOf("fitted"), "expected 12 numbers");
      geometry::ParamVector v;
      for (std::size_t p = 0; p < kNumParams; ++p) {
        v[static_cast<Eigen::Index>(p)] = one.numberValue(fitted[p], fmt::format("{}[{}]", one.pathOf("fitted"), p));
      }
      fits[one.at("sample").get<int>()] = v;
    }
    return fits;
  });
}

// ------------------------------------------------------------------ one point's work

// The point's work in its task directory: each piece read from its file when there with these
// settings, otherwise (`make`) done under the piece's lock and written, or (the merge) refused.
class PointWork {
 public:
  PointWork(const geometry::Calorimeter& calo, const DerivationOptions& o, std::string dir, const Json& settings,
            bool make)
      : calo_(calo), o_(o), dir_(std::move(dir)), settings_(settings), make_(make) {}

  Result<Sample> sample(int k, const std::function<void(const std::string&)>& say) const {
    const std::string file = sampleFile(dir_, k);
    return readOrMake<Sample>(
        file, [&] { return readSample(file, o_, k, settings_); },
        [&]() -> Result<Sample> {
          say(fmt::format("simulating the {} sample ({} events) into {}", kSampleNames[k], o_.events, file));
          auto s = simulateSample(calo_, o_, k, {});
          if (!s) return s.error();
          if (Status st = writeSample(file, k, *s, settings_); !st) return st.error();
          return s;
        });
  }

  Result<std::vector<Sample>> samples(const std::function<void(const std::string&)>& say) const {
    std::vector<Sample> all;
    for (int k = 0; k < 3; ++k) {
      auto s = sample(k, say);
      if (!s) return s.error();
      all.push_back(std::move(*s));
    }
    return all;
  }

  Result<DerivationReport> first(const std::function<void(const std::string&)>& say) const {
    const std::string file = firstStageFile(dir_);
    return readOrMake<DerivationReport>(
        file, [&] { return readFirstStage(file, settings_); },
        [&]() -> Result<DerivationReport> {
          auto all = samples(say);
          if (!all) return all.error();
          say(fmt::format("the first stage (depth, parting plane, nominal profile) into {}", file));
          auto report = firstStage(calib::FitGeometry::of(calo_.description()), o_, *all);
          if (!report) return report.error();
          if (Status st = io::writeOutputFile(file, derivationJson(*report, settings_).dump(2) + "\n",
                                              io::Placement::InDirectory);
              !st) {
            return st.error();
          }
          return report;
        });
  }

  Status response(const SampleBlock& block, const std::function<void(const std::string&)>& say) const {
    const std::string file = responseFile(dir_, block);
    std::error_code ec;
    if (fs::exists(file, ec)) {
      auto read = readResponseFile(file, settings_);
      bool whole = static_cast<bool>(read);
      for (int i = block.first; whole && i <= block.last; ++i) whole = read->contains(i);
      if (whole) return {};
    }
    auto stage = first(say);
    if (!stage) return stage.error();
    Json samples = Json::array();
    for (int i = block.first; i <= block.last; ++i) {
      auto fitted = fitResponseSample(calo_, o_, stage->corrections, i, {});
      if (!fitted) return fitted.error();
      Json f = Json::array(), t = Json::array();
      const AlignmentParameters truth = responseDraw(calo_, o_, i).truth;
      for (Param p : kAllParams) {
        f.push_back((*fitted)[p]);
        t.push_back(truth[p]);
      }
      samples.push_back({{"sample", i}, {"truth", t}, {"fitted", f}});
    }
    say(fmt::format("response {} fitted into {}", samplesText(block), file));
    const Json out = {{"format", kResponseFormat}, {"settings", settings_}, {"samples", samples}};
    return io::writeOutputFile(file, out.dump(2) + "\n", io::Placement::InDirectory);
  }

  // The merge: every response sample from the files of these settings.
  Result<std::vector<geometry::ParamVector>> responseFits() const {
    std::map<int, geometry::ParamVector> fits;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(dir_, ec)) {
      const std::string name = entry.path().filename().string();
      if (name.rfind("response-", 0) != 0 || entry.path().extension() != ".json") continue;
      auto read = readResponseFile(entry.path().string(), settings_);
      if (!read) return read.error();
      fits.merge(*read);
    }
    if (ec) return Error{fmt::format("{}: cannot list the directory: {}", dir_, ec.message())};
    std::vector<geometry::ParamVector> out;
    std::vector<std::size_t> absent;
    for (int i = 0; i < o_.responseSamples; ++i) {
      const auto it = fits.find(i);
      if (it == fits.end()) {
        absent.push_back(static_cast<std::size_t>(i));
      } else {
        out.push_back(it->second);
      }
    }
    if (!absent.empty()) {
      return Error{
          fmt::format("{}: response samples {} are not there with these settings (their tasks' "
                      "response-*.json files)",
                      dir_, taskRanges(absent))};
    }
    return out;
  }

 private:
  // The piece in `file`: read when it is there with these settings (`read` gives nullopt for
  // other settings); otherwise made and written under its lock (`make`), or, for the merge,
  // refused.
  template <typename T, typename Read, typename Make>
  Result<T> readOrMake(const std::string& file, Read&& read, Make&& make) const {
    std::optional<FileLock> lock;
    if (make_) {
      if (Status s = makeDirectory(); !s) return s.error();
      lock.emplace(file + ".lock");
      if (!lock->error().empty()) return Error{lock->error()};
    }
    std::error_code ec;
    if (fs::exists(file, ec)) {
      Result<std::optional<T>> got = read();
      if (!got && !make_) return got.error();
      if (got && *got) return std::move(**got);
    }
    if (!make_) return missing(file);
    return make();
  }
  Status makeDirectory() const {
    std::error_code ec;
    fs::create_directories(dir_, ec);
    if (ec) return Error{fmt::format("{}: cannot create the directory: {}", dir_, ec.message())};
    return {};
  }
  [[nodiscard]] Error missing(const std::string& file) const {
    return Error{
        fmt::format("{}: not there with this plan's settings (its task's output was removed or replaced)", file)};
  }

  const geometry::Calorimeter& calo_;
  const DerivationOptions& o_;
  std::string dir_;
  const Json& settings_;
  bool make_;
};

// The tasks of each point not yet derived: its three samples, its first stage, its response
// samples in blocks; a point already derived: one task that keeps it.
class DerivationJob final : public PlannedJob {
 public:
  DerivationJob(geometry::Calorimeter calo, DerivationOptions o, std::vector<GridPoint> points,
                std::vector<Json> settings, std::vector<std::string> inputs, std::string workDirectory,
                int samplesPerTask)
      : calo_(std::move(calo)),
        o_(std::move(o)),
        points_(std::move(points)),
        settings_(std::move(settings)),
        inputs_(std::move(inputs)),
        work_(std::move(workDirectory)) {
    std::size_t todo = 0;
    for (const auto& p : points_) todo += p.done ? 0 : 1;
    const int others = static_cast<int>(points_.size() + 3 * todo);
    blocks_ = o_.responseSamples > 0 ? sampleBlocks(o_.responseSamples, samplesPerTask,
                                                    static_cast<int>(std::max<std::size_t>(todo, 1)), others)
                                     : std::vector<SampleBlock>{};
    for (std::size_t p = 0; p < points_.size(); ++p) {
      if (points_[p].done) {
        refs_.push_back({p, Kind::Kept, 0, {}});
        continue;
      }
      for (int k = 0; k < 3; ++k) refs_.push_back({p, Kind::Sample, k, {}});
      refs_.push_back({p, Kind::FirstStage, 0, {}});
      for (const auto& b : blocks_) refs_.push_back({p, Kind::Response, 0, b});
    }
  }

  [[nodiscard]] std::vector<PlannedTask> tasks() const override {
    std::vector<PlannedTask> t;
    for (const auto& r : refs_) {
      const GridPoint& p = points_[r.point];
      const double mev = p.beamEnergy / units::MeV;
      const std::string dir = directoryOf(r.point);
      switch (r.kind) {
        case Kind::Kept:
          t.push_back({fmt::format("the corrections at {} MeV: derived with these settings already, kept", mev),
                       {absolute(p.file)},
                       inputs_});
          break;
        case Kind::Sample:
          t.push_back({fmt::format("the {} sample at {} MeV ({} events)", kSampleNames[r.sample], mev, o_.events),
                       {sampleFile(dir, r.sample)},
                       inputs_});
          break;
        case Kind::FirstStage:
          t.push_back({fmt::format("the first stage at {} MeV (depth, parting plane, nominal profile)", mev),
                       {firstStageFile(dir)},
                       inputs_});
          break;
        case Kind::Response:
          t.push_back(
              {fmt::format("response {} at {} MeV ({} events each)", samplesText(r.block), mev, o_.responseEvents),
               {responseFile(dir, r.block)},
               inputs_});
          break;
      }
    }
    return t;
  }

  Status runTask(std::size_t k, const TaskContext& context) const override {
    const Ref& r = refs_[k];
    const GridPoint& p = points_[r.point];
    if (derivedWith(p.file, settings_[r.point])) {
      context.say(fmt::format("{} holds corrections derived with the same settings: kept", p.file));
      return {};
    }
    if (r.kind == Kind::Kept) {
      return Error{fmt::format("{}: no longer holds the corrections derived with this plan's settings", p.file)};
    }
    DerivationOptions o = o_;
    o.simulation.generator.beamEnergy = p.beamEnergy;
    const PointWork work(calo_, o, directoryOf(r.point), settings_[r.point], true);
    Status done;
    switch (r.kind) {
      case Kind::Sample: {
        auto s = work.sample(r.sample, context.say);
        done = s ? Status{} : Status{s.error()};
        break;
      }
      case Kind::FirstStage: {
        auto f = work.first(context.say);
        if (f) {
          context.say(fmt::format("depth offset {:+.3f} ± {:.3f} cm", f->corrections.depthOffset / units::cm,
                                  f->depthOffsetError / units::cm));
        }
        done = f ? Status{} : Status{f.error()};
        break;
      }
      case Kind::Response:
        done = work.response(r.block, context.say);
        break;
      case Kind::Kept:
        break;
    }
    if (!done) return Error{fmt::format("at {} MeV: {}", p.beamEnergy / units::MeV, done.error().message)};
    return {};
  }

 private:
  enum class Kind { Kept, Sample, FirstStage, Response };
  struct Ref {
    std::size_t point;
    Kind kind;
    int sample;
    SampleBlock block;
  };
  static std::string absolute(const std::string& p) { return fs::absolute(p).lexically_normal().string(); }
  [[nodiscard]] std::string directoryOf(std::size_t point) const {
    return derivationTaskDirectory(work_, points_[point].beamEnergy);
  }

  geometry::Calorimeter calo_;
  DerivationOptions o_;
  std::vector<GridPoint> points_;
  std::vector<Json> settings_;
  std::vector<std::string> inputs_;
  std::string work_;
  std::vector<SampleBlock> blocks_;
  std::vector<Ref> refs_;
};

}  // namespace

Result<std::unique_ptr<PlannedJob>> derivationJob(geometry::Calorimeter calo, DerivationOptions options,
                                                  std::vector<GridPoint> points, std::vector<io::Json> settings,
                                                  std::vector<std::string> inputs, std::string workDirectory,
                                                  int samplesPerTask) {
  if (Status s = options.validate(); !s) return s.error();
  if (Status s = options.simulation.validate(calo.size()); !s) return s.error();
  return std::unique_ptr<PlannedJob>(
      std::make_unique<DerivationJob>(std::move(calo), std::move(options), std::move(points), std::move(settings),
                                      std::move(inputs), std::move(workDirectory), samplesPerTask));
}

Result<DerivationReport> mergeDerivation(const geometry::Calorimeter& calo, const DerivationOptions& o,
                                         const std::string& directory, const Json& settings) {
  if (Status s = o.validate(); !s) return s.error();
  const PointWork work(calo, o, directory, settings, false);
  auto report = work.first([](const std::string&) {});
  if (!report) return report.error();
  auto samples = work.samples([](const std::string&) {});
  if (!samples) return samples.error();
  std::vector<geometry::ParamVector> fits;
  if (o.responseSamples > 0) {
    auto read = work.responseFits();
    if (!read) return read.error();
    fits = std::move(*read);
  }
  if (Status s = lastStage(calo, calib::FitGeometry::of(calo.description()), o, *samples, fits, *report, {}); !s) {
    return s.error();
  }
  return report;
}

}  // namespace emcalign::validation
