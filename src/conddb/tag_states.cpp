#include "emcalign/conddb/tag_states.hpp"

#include <algorithm>

namespace emcalign::conddb {

std::string_view name(TagState s) {
  switch (s) {
    case TagState::Open:
      return "open";
    case TagState::Testing:
      return "testing";
    case TagState::Validated:
      return "validated";
    case TagState::Published:
      return "published";
    case TagState::Running:
      return "running";
    case TagState::Invalid:
      return "invalid";
  }
  return "?";
}

std::optional<TagState> tagStateNamed(std::string_view text) {
  for (TagState s : kAllTagStates) {
    if (name(s) == text) return s;
  }
  return std::nullopt;
}

std::vector<TagState> transitionsFrom(TagState from) {
  using S = TagState;
  switch (from) {
    case S::Open:
      return {S::Testing, S::Running, S::Published, S::Invalid};
    case S::Testing:
      return {S::Open, S::Validated, S::Invalid};
    case S::Validated:
      return {S::Published, S::Running, S::Invalid};
    case S::Running:
      return {S::Published, S::Invalid};
    case S::Published:
    case S::Invalid:
      return {};
  }
  return {};
}

bool transitionAllowed(TagState from, TagState to) {
  const auto next = transitionsFrom(from);
  return std::find(next.begin(), next.end(), to) != next.end();
}

IovWrites iovWrites(TagState s) {
  switch (s) {
    case TagState::Open:
      return IovWrites::Any;
    case TagState::Running:
      return IovWrites::Appended;
    default:
      return IovWrites::None;
  }
}

std::string whyNoIovs(TagState s) {
  switch (s) {
    case TagState::Testing:
      return "under test, its IOVs do not change (set it back to open to change them)";
    case TagState::Validated:
      return "its IOVs do not change (publish it, promote it into a running tag, or write a new tag)";
    case TagState::Published:
      return "its IOVs never change (write to a new tag)";
    case TagState::Invalid:
      return "never served or written to";
    default:
      return "";
  }
}

}  // namespace emcalign::conddb
