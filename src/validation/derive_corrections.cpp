#include "emcalign/validation/derive_corrections.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <numbers>
#include <set>

#include <fmt/format.h>
#include <Eigen/Cholesky>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/residual_model.hpp"
#include "emcalign/io/output_file.hpp"
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

// Simulates `events` events of the placement `truth` with the derivation's settings and this
// seed into the filler (selection, profiles); fails when none is selected.
Status simulateInto(const geometry::Calorimeter& calo, const DerivationOptions& o, const AlignmentParameters& truth,
                    std::uint64_t seed, std::int64_t events, calib::ProfileFiller& filler, std::string_view stage,
                    const DerivationProgress& progress) {
  sim::SimulationOptions so = o.simulation;
  so.seed = seed;
  auto simulation = sim::Simulation::create(calo, truth, so);
  if (!simulation) return simulation.error();
  const Status run = simulation->run(
      events, o.threads,
      [&](std::span<const ParticleRow> rows, std::span<const TruthRow>, std::span<const Hit>) {
        filler.addEvents(rows);
        return Status{};
      },
      [&](std::int64_t done) {
        if (progress) progress(stage, done, events);
      });
  if (!run) return run;
  if (Status sel = filler.checkSelected(); !sel) return Error{fmt::format("{}: {}", stage, sel.error().message)};
  return {};
}

Result<Sample> simulate(const geometry::Calorimeter& calo, const DerivationOptions& o, const AlignmentParameters& truth,
                        int k, std::string_view stage, const DerivationProgress& progress) {
  Sample s;
  s.truth = truth;
  // The residuals at the nominal depth only decide which tracks reach the EMC; the rows are
  // kept and their residuals rebuilt at every depth tried.
  calib::ProfileFiller filler(
      geometry::ShowerDepth::of(calo.description()), calib::SelectionOptions{}, {},
      [&](const ParticleRow& row, const calib::ParticleResidual&) { s.particles.push_back(row); });
  const std::uint64_t seed = Rng(o.seed ^ 0xC0EEC7ULL, static_cast<std::uint64_t>(k)).next();
  if (Status st = simulateInto(calo, o, truth, seed, o.events, filler, stage, progress); !st) return st.error();
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

// The response over the validation ranges: `responseSamples` samples with truths drawn as
// `emcalign validate` draws them, each fitted with the corrections of the report so far
// (statistical errors), and η̂ regressed on η with a constant.
Result<calib::FitResponse> measureResponse(const geometry::Calorimeter& calo, const DerivationOptions& o,
                                           DerivationReport& report, const DerivationProgress& progress) {
  calib::FitGeometry g = calib::FitGeometry::of(calo.description());
  g.apply(report.corrections);
  calib::ProfileOptions po;
  po.partingPlane = report.corrections.partingPlane;
  po.nominalProfile = report.corrections.nominalProfile;
  const int n = o.responseSamples;
  constexpr int kCols = 2 * static_cast<int>(kNumParams) + 1;  // 1, η, η·dx_rel
  Eigen::MatrixXd x(n, kCols), y(n, static_cast<int>(kNumParams));
  for (int i = 0; i < n; ++i) {
    const std::string stage = fmt::format("simulate response sample {}", i);
    Rng truthRng(o.seed ^ 0x2E5905EULL, static_cast<std::uint64_t>(i));
    const AlignmentParameters truth = drawTruth(o.responseRanges, calo.description().r1(), truthRng);
    calib::ProfileFiller filler(g.depth, calib::SelectionOptions{}, po);
    if (Status st = simulateInto(calo, o, truth, truthRng.next(), o.responseEvents, filler, stage, progress); !st) {
      return st.error();
    }
    auto fit = calib::fitProfiles(filler.fill().profiles.bins(0.0), g);
    if (!fit) return Error{fmt::format("{}: {}", stage, fit.error().message)};
    if (!usable(fit->status)) {
      return Error{fmt::format("{}: the fit's status is '{}'", stage, emcalign::name(fit->status))};
    }
    const double dxRel = (truth[Param::Dp1] + truth[Param::Dp2] + truth[Param::Dp3]) / 6.0;
    x(i, 0) = 1.0;
    x.row(i).segment(1, kNumParams) = truth.values.transpose();
    x.row(i).tail(kNumParams) = dxRel * truth.values.transpose();
    y.row(i) = fit->parameters.values.transpose();
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
  return response;
}

}  // namespace

Status DerivationOptions::validate() const {
  if (responseSamples != 0 && responseSamples < 50) return Error{"--response-samples must be 0 or at least 50"};
  if (responseSamples != 0 && responseEvents < 1000) return Error{"--response-events must be at least 1000"};
  if (events < 1000) return Error{"--events must be at least 1000 per sample"};
  if (!(shift > 0.0) || !(gap > 0.0)) return Error{"--shift and --gap must be positive"};
  if (!(depthLow < depthHigh)) return Error{"the depth search interval is empty"};
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

Result<DerivationReport> deriveCorrections(const geometry::Calorimeter& calo, const DerivationOptions& o,
                                           const DerivationProgress& progress) {
  if (Status s = o.validate(); !s) return s.error();
  const calib::FitGeometry nominalGeometry = calib::FitGeometry::of(calo.description());

  AlignmentParameters zero, shift, gap;
  shift[Param::Dx] = shift[Param::Dy] = shift[Param::Dz] = o.shift;
  gap[Param::Dp1] = gap[Param::Dp2] = gap[Param::Dp3] = 2.0 * o.gap;
  auto nominal = simulate(calo, o, zero, 0, "simulate nominal", progress);
  if (!nominal) return nominal.error();
  auto shifted = simulate(calo, o, shift, 1, "simulate shift", progress);
  if (!shifted) return shifted.error();
  auto gapped = simulate(calo, o, gap, 2, "simulate gap", progress);
  if (!gapped) return gapped.error();

  DerivationReport report;
  report.selectedEvents[0] = nominal->selectedEvents;
  report.selectedEvents[1] = shifted->selectedEvents;
  report.selectedEvents[2] = gapped->selectedEvents;

  if (progress) progress("depth", 0, 1);
  if (Status s = deriveDepth(*shifted, *nominal, nominalGeometry, o, report); !s) return s.error();
  if (progress) progress("depth", 1, 1);

  geometry::ShowerDepth depth = nominalGeometry.depth;
  depth.offset = report.corrections.depthOffset;
  calib::ProfileOptions po;
  po.sigmaSys = 0.0;
  const auto gb = profileOf(*gapped, depth, po), nb = profileOf(*nominal, depth, po);
  if (Status s = derivePartingPlane(gb, nb, gap, depth, nominalGeometry.radii, report); !s) return s.error();

  auto nominalProfile = nominalProfileOf(nb, po);
  if (!nominalProfile) return nominalProfile.error();
  report.corrections.nominalProfile = std::make_shared<const calib::NominalProfile>(std::move(*nominalProfile));

  // Step 4, the fit's response, with the corrections so far.
  if (o.responseSamples > 0) {
    auto response = measureResponse(calo, o, report, progress);
    if (!response) return response.error();
    report.corrections.response = std::make_shared<const calib::FitResponse>(*response);
  }

  // The nominal profile's statistical noise is common to every fit that uses the file: the
  // errors of a fit to it alone (statistical σ), with the model the file makes, are that
  // systematic error, per parameter.
  calib::FitGeometry corrected = nominalGeometry;
  corrected.apply(report.corrections);
  auto noise = calib::fitProfiles(nb, corrected);
  if (!noise) return Error{fmt::format("fit of the nominal profile: {}", noise.error().message)};
  report.nominalProfileErrors = noise->errors;

  if (progress) progress("closure fits", 0, 1);
  if (Status s = closureFits(*shifted, *gapped, nominalGeometry, o, report); !s) return s.error();
  if (progress) progress("closure fits", 1, 1);
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

namespace {

// Each energy point a task: derived and written unless its file holds corrections derived with
// the same settings.
class DerivationJob final : public PlannedJob {
 public:
  DerivationJob(geometry::Calorimeter calo, DerivationOptions o, std::vector<GridPoint> points,
                std::vector<Json> settings, bool grid, std::vector<std::string> inputs)
      : calo_(std::move(calo)),
        o_(std::move(o)),
        points_(std::move(points)),
        settings_(std::move(settings)),
        grid_(grid),
        inputs_(std::move(inputs)) {}

  std::vector<PlannedTask> tasks() const override {
    std::vector<PlannedTask> t;
    for (const auto& p : points_) {
      t.push_back({fmt::format("the corrections at {} MeV ({} events per sample, {} response samples of {})",
                               p.beamEnergy / units::MeV, o_.events, o_.responseSamples, o_.responseEvents),
                   {std::filesystem::absolute(p.file).lexically_normal().string()},
                   inputs_});
    }
    return t;
  }

  Status runTask(std::size_t k, const TaskContext& context) const override {
    const auto& say = context.say;
    const GridPoint& p = points_[k];
    if (derivedWith(p.file, settings_[k])) {
      say(fmt::format("{} holds corrections derived with the same settings: kept", p.file));
      return {};
    }
    if (grid_) {
      std::error_code ec;
      std::filesystem::create_directories(std::filesystem::path(p.file).parent_path(), ec);
      if (ec) return Error{fmt::format("{}: cannot create the directory: {}", p.file, ec.message())};
    }
    DerivationOptions o = o_;
    o.simulation.generator.beamEnergy = p.beamEnergy;
    auto report = deriveCorrections(calo_, o);
    if (!report) return Error{fmt::format("at {} MeV: {}", p.beamEnergy / units::MeV, report.error().message)};
    say(fmt::format("depth offset {:+.3f} ± {:.3f} cm", report->corrections.depthOffset / units::cm,
                    report->depthOffsetError / units::cm));
    return io::writeOutputFile(p.file, derivationJson(*report, settings_[k]).dump(2) + "\n",
                               grid_ ? io::Placement::InDirectory : io::Placement::Named);
  }

 private:
  geometry::Calorimeter calo_;
  DerivationOptions o_;
  std::vector<GridPoint> points_;
  std::vector<Json> settings_;
  bool grid_;
  std::vector<std::string> inputs_;
};

}  // namespace

std::unique_ptr<PlannedJob> derivationJob(geometry::Calorimeter calo, DerivationOptions options,
                                          std::vector<GridPoint> points, std::vector<io::Json> settings, bool grid,
                                          std::vector<std::string> inputs) {
  return std::make_unique<DerivationJob>(std::move(calo), std::move(options), std::move(points), std::move(settings),
                                         grid, std::move(inputs));
}

}  // namespace emcalign::validation
