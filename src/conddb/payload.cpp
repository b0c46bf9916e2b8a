#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/fit_status.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/utf8.hpp"
#include "lenient_json.hpp"

namespace emcalign::conddb {

using io::Json;

Status checkTagName(std::string_view tag) {
  if (tag.empty() || tag.size() > 100) {
    return Error{fmt::format("tag '{}': a name has 1 to 100 characters", printable(tag.substr(0, 100)))};
  }
  for (char c : tag) {
    const bool ok =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-' || c == '.';
    if (!ok) return Error{fmt::format("tag '{}': a name is made of letters, digits, '_', '-' and '.'", printable(tag))};
  }
  return {};
}

std::string Payload::hash() const { return sha256(content.dump()); }

namespace {

using lenient::objectAt;

// The number at `key` of an object; NaN when there is none.
double numberOrNaN(const Json& j, std::string_view key) {
  return lenient::numberAt(j, key).value_or(std::numeric_limits<double>::quiet_NaN());
}

}  // namespace

Json Payload::parameterFile() const {
  Json out = content.contains("alignment") ? content["alignment"] : Json::object();
  return out;
}

calib::ModelIdentity Payload::modelIdentity() const {
  calib::ModelIdentity m;
  if (auto s = sigmaSysChoice()) m.sigmaSys = *s;
  m.corrections = correctionsFile();
  m.correctionsSha256 = correctionsSha256();
  if (!m.corrections.empty()) {
    m.kind = calib::ModelIdentity::Kind::Corrections;
    return m;
  }
  // A fit result stored with `conditions put` names its corrections under model_corrections.
  const Json& provenance = objectAt(content, "provenance");
  const auto it = provenance.find("model_corrections");
  if (it == provenance.end() || !it->is_object()) return m;
  for (const char* key : {"response", "parting_plane_response", "nominal_profile"}) {
    if (auto file = io::stringAt(*it, key)) {
      m.kind = calib::ModelIdentity::Kind::Corrections;
      m.corrections = *file;
      return m;
    }
  }
  m.kind = calib::ModelIdentity::Kind::Paper;
  m.depthOffsetCm = depthOffsetCm().value_or(0.0);
  return m;
}

std::optional<double> Payload::depthOffsetCm() const {
  const Json& provenance = objectAt(content, "provenance");
  if (!provenance.contains("model_corrections")) return std::nullopt;
  const double offset = numberOrNaN(provenance["model_corrections"], "depth_offset_cm");
  return std::isnan(offset) ? 0.0 : offset;
}

StoredValues Payload::values() const {
  const Json& alignment = objectAt(content, "alignment");
  const Json& parameters = objectAt(alignment, "parameters");
  const Json& errors = objectAt(alignment, "errors");
  const Json& statistical = objectAt(alignment, "statistical_errors");
  const Json& derived = objectAt(alignment, "derived");
  StoredValues out;
  for (std::size_t k = 0; k < kAllQuantities.size(); ++k) {
    const std::string n(kAllQuantities[k].name());
    if (k < kNumParams) {
      out[k] = {numberOrNaN(parameters, n), numberOrNaN(errors, n), numberOrNaN(statistical, n)};
    } else {
      const Json& d = objectAt(derived, n);
      out[k] = {numberOrNaN(d, "value"), numberOrNaN(d, "error"), numberOrNaN(d, "statistical_error")};
    }
  }
  return out;
}

std::vector<std::pair<std::string, std::string>> Payload::inputDigests() const {
  std::vector<std::pair<std::string, std::string>> out;
  const Json& digests = objectAt(objectAt(content, "provenance"), "input_sha256");
  for (const auto& [file, sha] : digests.items()) {
    if (sha.is_string()) out.emplace_back(file, sha.get<std::string>());
  }
  return out;
}

std::string Payload::correctionsFile() const {
  return io::stringAt(objectAt(content, "provenance"), "corrections").value_or("");
}

std::string Payload::correctionsSha256() const {
  return io::stringAt(objectAt(content, "provenance"), "corrections_sha256").value_or("");
}

std::optional<std::int64_t> Payload::selectedEvents() const {
  const auto n = lenient::integerAt(content, "selected_events");
  return n && *n >= 0 ? n : std::nullopt;
}

Result<calib::SigmaSysChoice> Payload::sigmaSysChoice() const {
  const Json& alignment = objectAt(content, "alignment");
  const auto it = alignment.find("sigma_sys");
  // Payloads made before the choice existed were fitted with the paper's.
  const Json recorded = it != alignment.end() && it->is_object() ? *it : Json{{"method", "spec"}};
  auto choice = calib::sigmaSysChoiceFromJson(recorded);
  if (!choice) {
    return Error{fmt::format("sigma_sys {}: not one a campaign makes ({})", recorded.dump(), choice.error().message)};
  }
  return choice;
}

Result<Payload> makePayload(const Json& in, double r1, std::string_view source, Json provenance) {
  // The parameters must read as an input (a usable fit result, plausible values).
  auto file = io::parseAlignmentFile(in, r1, source);
  if (!file) return file.error();
  Json alignment = io::alignmentToJson(file->parameters);
  // What a fit result says about its parameters travels with them.
  for (const char* key : {"errors", "statistical_errors", "systematic_errors", "covariance", "correlation", "derived",
                          "chi2", "ndf", "p_value", "status", "warnings", "notes", "sigma_sys"}) {
    if (in.contains(key)) alignment[key] = in[key];
  }
  Json p = Json{{"format", kPayloadFormat}, {"alignment", alignment}};
  if (in.contains("input") && in["input"].is_object()) {
    const Json& input = in["input"];
    if (input.contains("cut_flow") && input["cut_flow"].is_object() && !input["cut_flow"].empty()) {
      p["selected_events"] = input["cut_flow"].back();
    }
    if (input.contains("files")) provenance["inputs"] = input["files"];
    if (input.contains("model_corrections")) provenance["model_corrections"] = input["model_corrections"];
  }
  if (in.contains("software")) provenance["fit_software"] = in["software"];
  p["provenance"] = std::move(provenance);
  return Payload{std::move(p)};
}

}  // namespace emcalign::conddb
