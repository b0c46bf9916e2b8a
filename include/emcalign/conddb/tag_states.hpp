#pragma once
// The states of a conditions tag and the transitions between them, in one place (Belle II's
// global tag states; docs/campaign.md "Tag states" has the table).
//
//   open       new; IOVs may be added (never overlapping)
//   testing    under test: its IOVs do not change (back to open to change them)
//   validated  tested and accepted: ready to be published or promoted into a running tag
//   published  immutable, for ever
//   running    a prompt loop's: IOVs only appended after its last one (and promotions)
//   invalid    withdrawn: kept and listed, never served or written, whatever the snapshot

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace emcalign::conddb {

enum class TagState { Open, Testing, Validated, Published, Running, Invalid };

inline constexpr TagState kAllTagStates[] = {TagState::Open,      TagState::Testing, TagState::Validated,
                                             TagState::Published, TagState::Running, TagState::Invalid};

/// "open", "testing", "validated", "published", "running", "invalid".
std::string_view name(TagState s);
/// The state of that name; none for any other text.
std::optional<TagState> tagStateNamed(std::string_view text);

/// The states a tag in `from` may be set to: open → testing | running | published | invalid;
/// testing → open | validated | invalid; validated → published | running | invalid;
/// running → published | invalid; published and invalid are final.
std::vector<TagState> transitionsFrom(TagState from);
bool transitionAllowed(TagState from, TagState to);

/// How the IOVs of a tag in a state may be written.
enum class IovWrites {
  Any,       ///< open: anywhere they do not overlap
  Appended,  ///< running: only after its last IOV
  None,      ///< every other state
};
IovWrites iovWrites(TagState s);

/// Why a tag in state `s` takes no IOV, for an error message after "tag 'T' is STATE: " ("" when
/// it takes them).
std::string whyNoIovs(TagState s);

}  // namespace emcalign::conddb
