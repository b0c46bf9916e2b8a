#include "emcalign/calib/corrections.hpp"

#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/SVD>

#include "emcalign/core/beam_energy.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/io/strict_json.hpp"

namespace emcalign::calib {

Status checkDepthOffset(double offset, const std::string& corrections) {
  if (!(std::abs(offset) <= kMaxDepthOffset * units::cm)) {
    return Error{fmt::format("the depth offset {:.6g} cm is beyond the plausible ±{} cm (in cm: given in mm?)",
                             offset / units::cm, kMaxDepthOffset)};
  }
  if (offset != 0.0 && !corrections.empty()) {
    return Error{"a depth offset and corrections: the corrections bring their own depth offset"};
  }
  return {};
}

using io::Json;

Result<PartingPlaneResponse> PartingPlaneResponse::create(std::vector<double> plusWeight) {
  const int n = static_cast<int>(plusWeight.size());
  if (n < 4 || n % 4 != 0) {
    return Error{fmt::format("parting-plane response: {} phi columns; need a multiple of 4 (the profiles have 16)", n)};
  }
  for (int k = 0; k < n; ++k) {
    const double w = plusWeight[static_cast<std::size_t>(k)];
    if (!(w >= 0.0 && w <= 1.0)) {
      return Error{fmt::format("parting-plane response: column {}: a weight must lie in [0, 1], got {}", k, w)};
    }
    if (!nextToPlane(k, n) && w != hardWeight(k, n)) {
      return Error{
          fmt::format("parting-plane response: column {} is away from the plane and must keep its hard "
                      "weight {}, got {}",
                      k, hardWeight(k, n), w)};
    }
  }
  PartingPlaneResponse r;
  r.weight_ = std::move(plusWeight);
  return r;
}

bool PartingPlaneResponse::nextToPlane(int iPhi, int phiBins) {
  const double lo = 360.0 * iPhi / phiBins, hi = 360.0 * (iPhi + 1) / phiBins;
  return (lo <= 90.0 && 90.0 <= hi) || (lo <= 270.0 && 270.0 <= hi);
}

double PartingPlaneResponse::hardWeight(int iPhi, int phiBins) {
  const double centre = (iPhi + 0.5) * 2.0 * std::numbers::pi / phiBins;
  return std::cos(centre) >= 0.0 ? 1.0 : 0.0;
}

Status NominalProfile::validate() const {
  const auto n = static_cast<std::size_t>(phiBins) * static_cast<std::size_t>(thetaBins);
  if (phiBins < 1 || thetaBins < 1) return Error{"nominal profile: need at least one bin"};
  if (yPhi.size() != n || sigmaPhi.size() != n || yTheta.size() != n || sigmaTheta.size() != n) {
    return Error{fmt::format("nominal profile: every column needs phi_bins × theta_bins = {} values", n)};
  }
  for (std::size_t k = 0; k < n; ++k) {
    const bool missing = std::isnan(yPhi[k]);
    if (missing != std::isnan(yTheta[k]) || missing != std::isnan(sigmaPhi[k]) ||
        missing != std::isnan(sigmaTheta[k])) {
      return Error{fmt::format("nominal profile: bin {}: either all four values or none", k)};
    }
    if (!missing && (!std::isfinite(yPhi[k]) || !std::isfinite(yTheta[k]) || !(sigmaPhi[k] >= 0.0) ||
                     !(sigmaTheta[k] >= 0.0) || !std::isfinite(sigmaPhi[k]) || !std::isfinite(sigmaTheta[k]))) {
      return Error{fmt::format("nominal profile: bin {}: values must be finite and sigmas non-negative", k)};
    }
  }
  return {};
}

namespace {

// A response matrix in file units (deg and cm; row j fitted, column k true): element (j, k)
// scaled by fileUnit(k)/fileUnit(j). `toFile` false converts back.
ResponseMatrix inUnits(const ResponseMatrix& m, bool toFile) {
  ResponseMatrix out;
  for (std::size_t j = 0; j < kNumParams; ++j) {
    for (std::size_t k = 0; k < kNumParams; ++k) {
      const double scale = geometry::AlignmentParameters::fileUnit(kAllParams[k]) /
                           geometry::AlignmentParameters::fileUnit(kAllParams[j]);
      const auto jj = static_cast<Eigen::Index>(j), kk = static_cast<Eigen::Index>(k);
      out(jj, kk) = toFile ? m(jj, kk) * scale : m(jj, kk) / scale;
    }
  }
  return out;
}

Json parameterNamesJson() {
  Json names = Json::array();
  for (auto n : kParamNames) names.push_back(std::string(n));
  return names;
}

Json matrixJson(const ResponseMatrix& m) {
  Json rows = Json::array();
  for (Eigen::Index j = 0; j < m.rows(); ++j) rows.push_back(std::vector<double>(m.row(j).begin(), m.row(j).end()));
  return rows;
}

// 12 rows of 12 numbers, as written (file units).
Result<ResponseMatrix> readMatrix(const Json& m, std::string_view key) {
  ResponseMatrix out;
  if (!m.is_array() || m.size() != kNumParams) return Error{fmt::format("'{}' must have 12 rows", key)};
  for (std::size_t j = 0; j < kNumParams; ++j) {
    if (!m[j].is_array() || m[j].size() != kNumParams) {
      return Error{fmt::format("'{}' row {} must have 12 numbers", key, j)};
    }
    for (std::size_t k = 0; k < kNumParams; ++k) {
      if (!m[j][k].is_number()) return Error{fmt::format("'{}' row {} column {}: expected a number", key, j, k)};
      out(static_cast<Eigen::Index>(j), static_cast<Eigen::Index>(k)) = m[j][k].get<double>();
    }
  }
  return out;
}

Result<FitResponse> parseResponse(const Json& p, std::string_view source) {
  const auto fail = [&](const std::string& what) { return Error{fmt::format("{}: key 'response': {}", source, what)}; };
  const bool gap = p.is_object() && p.contains("gap_matrix");
  if (!p.is_object() || p.size() != (gap ? 4u : 3u) || !p.contains("parameters") || !p.contains("matrix") ||
      !p.contains("offset")) {
    return fail(
        "expected {\"parameters\": [the 12 names], \"matrix\": 12 rows of 12 numbers, \"offset\": 12 numbers, "
        "optionally \"gap_matrix\": 12 rows of 12 numbers}");
  }
  if (p["parameters"] != parameterNamesJson()) {
    return fail(fmt::format("'parameters' must be [{}]", fmt::join(kParamNames, ", ")));
  }
  FitResponse response;
  auto matrix = readMatrix(p["matrix"], "matrix");
  if (!matrix) return fail(matrix.error().message);
  response.matrix = inUnits(*matrix, false);
  if (gap) {
    auto g = readMatrix(p["gap_matrix"], "gap_matrix");
    if (!g) return fail(g.error().message);
    response.gapMatrix = inUnits(*g, false);
  }
  const Json& c = p["offset"];
  if (!c.is_array() || c.size() != kNumParams) return fail("'offset' must have 12 numbers");
  for (std::size_t j = 0; j < kNumParams; ++j) {
    if (!c[j].is_number()) return fail(fmt::format("'offset' {}: expected a number", j));
    response.offset[static_cast<Eigen::Index>(j)] =
        c[j].get<double>() * geometry::AlignmentParameters::fileUnit(kAllParams[j]);
  }
  if (Status s = response.validate(); !s) return fail(s.error().message);
  return response;
}

Json responseJson(const FitResponse& response) {
  Json offset = Json::array();
  for (std::size_t j = 0; j < kNumParams; ++j) {
    offset.push_back(response.offset[static_cast<Eigen::Index>(j)] /
                     geometry::AlignmentParameters::fileUnit(kAllParams[j]));
  }
  Json out = {
      {"parameters", parameterNamesJson()}, {"matrix", matrixJson(inUnits(response.matrix, true))}, {"offset", offset}};
  if (!response.gapMatrix.isZero(0.0)) out["gap_matrix"] = matrixJson(inUnits(response.gapMatrix, true));
  return out;
}

}  // namespace

Status FitResponse::validate() const {
  if (!matrix.allFinite() || !offset.allFinite() || !gapMatrix.allFinite()) {
    return Error{"the response has a value that is not finite"};
  }
  const ResponseMatrix gapFile = inUnits(gapMatrix, true);
  for (std::size_t j = 0; j < kNumParams; ++j) {
    for (std::size_t k = 0; k < kNumParams; ++k) {
      const double g = gapFile(static_cast<Eigen::Index>(j), static_cast<Eigen::Index>(k));
      if (std::abs(g) > 1.0) {
        return Error{
            fmt::format("the response's gap term of {} in {} is {:.4g} per cm of dx_rel: beyond the plausible 1",
                        kParamNames[j], kParamNames[k], g)};
      }
    }
  }
  for (std::size_t j = 0; j < kNumParams; ++j) {
    const double unit = geometry::AlignmentParameters::fileUnit(kAllParams[j]);
    if (std::abs(offset[static_cast<Eigen::Index>(j)] / unit) > 0.5) {
      return Error{fmt::format("the response's offset of {} is {:.4g} (deg or cm): beyond the plausible 0.5",
                               kParamNames[j], offset[static_cast<Eigen::Index>(j)] / unit)};
    }
  }
  const ResponseMatrix file = inUnits(matrix, true);
  for (std::size_t k = 0; k < kNumParams; ++k) {
    const double d = file(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(k));
    if (!(d >= 0.5 && d <= 1.5)) {
      return Error{
          fmt::format("the response of {} to itself is {:.4g}: a fit that far from its truth is not a "
                      "correction (0.5 to 1.5 expected)",
                      kParamNames[k], d)};
    }
  }
  const Eigen::JacobiSVD<ResponseMatrix::Base> svd(file);
  const double condition = svd.singularValues()(0) / svd.singularValues()(kNumParams - 1);
  if (!(condition < 100.0)) {
    return Error{
        fmt::format("the response matrix is nearly singular (condition number {:.3g} in deg and cm)", condition)};
  }
  return {};
}

namespace {

// The keys of a corrections file: only those it may have, and its format.
Status checkCorrectionsKeys(const Json& j, std::string_view source) {
  if (!j.is_object()) return Error{fmt::format("{}: expected a JSON object", source)};
  if (Status kind = io::expectFormat(j, kCorrectionsFormat, "a corrections file", source); !kind) return kind.error();
  if (Status s = io::strict::checkKeys(j,
                                       {"format", "beam_energy_mev", "depth_offset_cm", "parting_plane",
                                        "nominal_profile", "response", "systematic_errors", "derived_from"},
                                       {.source = source});
      !s) {
    return s;
  }
  if (!j.contains("format") || j["format"] != kCorrectionsFormat) {
    return Error{fmt::format("{}: key 'format': expected \"{}\"", source, kCorrectionsFormat)};
  }
  return {};
}

// "parting_plane": {"phi_bins": 16, "plus_weight": [16 numbers]}.
Result<std::shared_ptr<const PartingPlaneResponse>> parsePartingPlane(const Json& p, std::string_view source) {
  if (!p.is_object() || p.size() != 2 || !p.contains("phi_bins") || !p.contains("plus_weight")) {
    return Error{fmt::format("{}: key 'parting_plane': expected {{\"phi_bins\": 16, \"plus_weight\": [...]}}", source)};
  }
  auto bins = io::integerIn(p["phi_bins"], kProfilePhiBins, kProfilePhiBins, source, "parting_plane.phi_bins");
  if (!bins)
    return Error{fmt::format("{} (the response belongs to the {} phi bins of the profiles)", bins.error().message,
                             kProfilePhiBins)};
  if (!p["plus_weight"].is_array() || p["plus_weight"].size() != static_cast<std::size_t>(*bins)) {
    return Error{fmt::format("{}: key 'parting_plane.plus_weight': expected {} numbers", source, *bins)};
  }
  std::vector<double> w;
  for (const auto& x : p["plus_weight"]) {
    if (!x.is_number()) return Error{fmt::format("{}: key 'parting_plane.plus_weight': expected numbers", source)};
    w.push_back(x.get<double>());
  }
  auto r = PartingPlaneResponse::create(std::move(w));
  if (!r) return Error{fmt::format("{}: key 'parting_plane': {}", source, r.error().message)};
  return std::make_shared<const PartingPlaneResponse>(std::move(*r));
}

// "nominal_profile": the bins' mean residuals and their errors (numbers or null).
Result<std::shared_ptr<const NominalProfile>> parseNominalProfile(const Json& p, std::string_view source) {
  static constexpr const char* kKeys[] = {"phi_bins", "theta_bins", "y_phi", "sigma_phi", "y_theta", "sigma_theta"};
  if (!p.is_object() || p.size() != 6) {
    return Error{fmt::format("{}: key 'nominal_profile': expected an object with {}", source, fmt::join(kKeys, ", "))};
  }
  for (const char* key : kKeys) {
    if (!p.contains(key)) return Error{fmt::format("{}: key 'nominal_profile.{}': missing", source, key)};
  }
  NominalProfile t;
  auto phiBins = io::integerIn(p["phi_bins"], kProfilePhiBins, kProfilePhiBins, source, "nominal_profile.phi_bins");
  auto thetaBins =
      io::integerIn(p["theta_bins"], kProfileThetaBins, kProfileThetaBins, source, "nominal_profile.theta_bins");
  if (!phiBins || !thetaBins) {
    return Error{fmt::format("{} (the nominal profile belongs to the {} x {} bins of the profiles)",
                             (!phiBins ? phiBins : thetaBins).error().message, kProfilePhiBins, kProfileThetaBins)};
  }
  t.phiBins = static_cast<int>(*phiBins);
  t.thetaBins = static_cast<int>(*thetaBins);
  for (const char* key : {"y_phi", "sigma_phi", "y_theta", "sigma_theta"}) {
    if (!p[key].is_array()) return Error{fmt::format("{}: key 'nominal_profile.{}': expected an array", source, key)};
    std::vector<double>& v = key == std::string_view("y_phi")       ? t.yPhi
                             : key == std::string_view("sigma_phi") ? t.sigmaPhi
                             : key == std::string_view("y_theta")   ? t.yTheta
                                                                    : t.sigmaTheta;
    for (const auto& x : p[key]) {
      if (x.is_null()) {
        v.push_back(std::numeric_limits<double>::quiet_NaN());
      } else if (x.is_number()) {
        v.push_back(x.get<double>());
      } else {
        return Error{fmt::format("{}: key 'nominal_profile.{}': expected numbers or null", source, key)};
      }
    }
  }
  if (Status st = t.validate(); !st)
    return Error{fmt::format("{}: key 'nominal_profile': {}", source, st.error().message)};
  return std::make_shared<const NominalProfile>(std::move(t));
}

// Systematic errors belong to the corrections they were measured with (their digest).
Status checkSystematicsBelong(const ModelCorrections& c, std::string_view source) {
  if (!c.systematics) return {};
  if (!c.systematics->study.contains("corrections_fnv1a")) {
    return Error{fmt::format(
        "{}: key 'systematic_errors.study.corrections_fnv1a': missing: systematic errors belong to the corrections "
        "they were measured with (`emcalign systematics --write-corrections` writes them with their digest)",
        source)};
  }
  const Json& measured = c.systematics->study["corrections_fnv1a"];
  if (const std::string own = correctionsDigest(c); !measured.is_string() || measured.get<std::string>() != own) {
    return Error{fmt::format(
        "{}: key 'systematic_errors': measured with other corrections (fnv1a {}, this file's {}): the file was "
        "changed after `emcalign systematics --write-corrections`; run the study again",
        source, measured.is_string() ? measured.get<std::string>() : measured.dump(), own)};
  }
  return {};
}

}  // namespace

Result<ModelCorrections> parseCorrections(const Json& j, std::string_view source) {
  if (Status s = checkCorrectionsKeys(j, source); !s) return s.error();
  ModelCorrections c;
  if (j.contains("beam_energy_mev")) {
    const Json& e = j["beam_energy_mev"];
    if (!e.is_number() || !(e.get<double>() >= kMinBeamEnergy && e.get<double>() <= kMaxBeamEnergy)) {
      return Error{fmt::format("{}: key 'beam_energy_mev': expected the beam energy in MeV, {} to {}", source,
                               kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV)};
    }
    c.beamEnergy = e.get<double>() * units::MeV;
  }
  if (!j.contains("depth_offset_cm") || !j["depth_offset_cm"].is_number() ||
      !std::isfinite(j["depth_offset_cm"].get<double>())) {
    return Error{fmt::format("{}: key 'depth_offset_cm': expected a finite number (cm)", source)};
  }
  c.depthOffset = j["depth_offset_cm"].get<double>() * units::cm;
  if (std::abs(c.depthOffset) > kMaxDepthOffset) {
    return Error{
        fmt::format("{}: key 'depth_offset_cm': {:.6g} cm is beyond the plausible ±{} cm (the offset is in cm: "
                    "given in mm?)",
                    source, c.depthOffset / units::cm, kMaxDepthOffset / units::cm)};
  }
  if (j.contains("parting_plane")) {
    auto p = parsePartingPlane(j["parting_plane"], source);
    if (!p) return p.error();
    c.partingPlane = std::move(*p);
  }
  if (j.contains("nominal_profile")) {
    auto p = parseNominalProfile(j["nominal_profile"], source);
    if (!p) return p.error();
    c.nominalProfile = std::move(*p);
  }
  if (j.contains("response")) {
    auto r = parseResponse(j["response"], source);
    if (!r) return r.error();
    c.response = std::make_shared<const FitResponse>(*r);
  }
  if (j.contains("systematic_errors")) {
    auto e = parseSystematicErrors(j["systematic_errors"], source);
    if (!e) return e.error();
    c.systematics = std::make_shared<const SystematicErrors>(std::move(*e));
  }
  if (j.contains("derived_from")) c.derivedFrom = j["derived_from"];
  if (Status s = checkSystematicsBelong(c, source); !s) return s.error();
  return c;
}

Result<SystematicErrors> parseSystematicErrors(const Json& j, std::string_view source) {
  if (!j.is_object()) return Error{fmt::format("{}: key 'systematic_errors': expected an object", source)};
  if (Status s =
          io::strict::checkKeys(j, {"errors", "components", "study"}, {.source = source, .path = "systematic_errors"});
      !s) {
    return s.error();
  }
  if (!j.contains("errors") || !j["errors"].is_object()) {
    return Error{fmt::format("{}: key 'systematic_errors.errors': expected an object {{parameter: error}}", source)};
  }
  SystematicErrors out;
  for (const auto& [key, value] : j["errors"].items()) {
    const std::optional<Quantity> q = quantityFromName(key);
    if (!q || q->isDirection()) {
      return Error{fmt::format(
          "{}: key 'systematic_errors.errors.{}': unknown parameter (the 12 of the fit, and beta, mu, dx_rel)", source,
          key)};
    }
    if (!value.is_number() || !(value.get<double>() >= 0.0 && value.get<double>() <= kMaxSystematicError)) {
      return Error{fmt::format("{}: key 'systematic_errors.errors.{}': expected a number in [0, {}] (deg or cm)",
                               source, key, kMaxSystematicError)};
    }
    out.errors.emplace(*q, value.get<double>());
  }
  for (Param p : kAllParams) {
    if (!out.errors.contains(p)) {
      return Error{fmt::format("{}: key 'systematic_errors.errors.{}': missing (every parameter of the fit has one)",
                               source, name(p))};
    }
  }
  for (const char* key : {"components", "study"}) {
    if (!j.contains(key)) continue;
    if (!j[key].is_object())
      return Error{fmt::format("{}: key 'systematic_errors.{}': expected an object", source, key)};
    (key == std::string_view("study") ? out.study : out.components) = j[key];
  }
  return out;
}

Json systematicErrorsJson(const SystematicErrors& s) {
  Json errors = Json::object();
  // The fit's parameters in their order, then the derived ones.
  for (Param p : kAllParams) {
    if (auto it = s.errors.find(p); it != s.errors.end()) errors[std::string(name(p))] = it->second;
  }
  for (const auto& [q, value] : s.errors) {
    const std::string n(q.name());
    if (!errors.contains(n)) errors[n] = value;
  }
  Json j{{"errors", errors}};
  if (!s.components.empty()) j["components"] = s.components;
  if (!s.study.empty()) j["study"] = s.study;
  return j;
}

Result<geometry::ShowerDepth> showerDepthWith(const geometry::DetectorDescription& detector, double offset,
                                              const std::string& correctionsFile) {
  auto depth = geometry::ShowerDepth::of(detector);
  depth.offset = offset;
  if (!correctionsFile.empty()) {
    auto c = readCorrections(correctionsFile);
    if (!c) return c.error();
    depth.offset = c->depthOffset;
  }
  return depth;
}

Result<ModelCorrections> readCorrections(const std::string& path) {
  auto text = io::readTextFile(path);
  if (!text) return text.error();
  auto j = io::parseJson(*text, path);
  if (!j) return j.error();
  return parseCorrections(*j, path);
}

Json correctionsJson(const ModelCorrections& c) {
  Json j{{"format", kCorrectionsFormat}};
  if (!std::isnan(c.beamEnergy)) j["beam_energy_mev"] = c.beamEnergy / units::MeV;
  j["depth_offset_cm"] = c.depthOffset / units::cm;
  if (c.partingPlane) {
    j["parting_plane"] = {{"phi_bins", c.partingPlane->phiBins()}, {"plus_weight", c.partingPlane->weights()}};
  }
  if (c.nominalProfile) {
    const NominalProfile& t = *c.nominalProfile;
    auto array = [](const std::vector<double>& v) {
      Json a = Json::array();
      for (double x : v) a.push_back(std::isnan(x) ? Json(nullptr) : Json(x));
      return a;
    };
    j["nominal_profile"] = {{"phi_bins", t.phiBins},      {"theta_bins", t.thetaBins},
                            {"y_phi", array(t.yPhi)},     {"sigma_phi", array(t.sigmaPhi)},
                            {"y_theta", array(t.yTheta)}, {"sigma_theta", array(t.sigmaTheta)}};
  }
  if (c.response) j["response"] = responseJson(*c.response);
  if (c.systematics) j["systematic_errors"] = systematicErrorsJson(*c.systematics);
  if (!c.derivedFrom.empty()) j["derived_from"] = c.derivedFrom;
  return j;
}

std::string correctionsDigest(const ModelCorrections& c) {
  Json j = correctionsJson(c);
  j.erase("systematic_errors");  // what the corrections do, not what is known of them
  const std::string text = j.dump();
  std::uint64_t digest = 0xcbf29ce484222325ULL;  // FNV-1a
  for (unsigned char ch : text) digest = (digest ^ ch) * 0x100000001b3ULL;
  return fmt::format("{:016x}", digest);
}

}  // namespace emcalign::calib
