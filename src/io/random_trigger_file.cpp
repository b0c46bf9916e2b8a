// Random-trigger files (io/random_trigger_file.hpp): HDF5 and CSV, written whole, read whole.

#include "emcalign/io/random_trigger_file.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <string_view>
#include <tuple>

#include <fmt/format.h>

#include "emcalign/io/csv.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/io/file_kind.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/io/output_file.hpp"
#include "hdf5_internal.hpp"

namespace emcalign::io {

namespace {

using detail::Hid;
using detail::Kind;

constexpr const char* kGroup = "random_trigger";
constexpr const char* kHitsGroup = "hits";
constexpr hsize_t kChunk = 16384;
// A CSV file of the largest allowed size: 40 M hits of ~25 characters.
constexpr std::size_t kMaxCsvBytes = std::size_t{1} << 30;

// The event files' rule (io::formatOf): ".csv" in any case, or "-", is CSV.
bool isCsv(const std::string& path) { return formatOf(path) == EventFormat::Csv; }

// ------------------------------------------------------------------------------- writing

Status writeCsv(const std::string& path, const RandomTriggerEvents& events,
                const std::vector<std::pair<std::string, std::string>>& attributes, Placement placement) {
  std::string text = fmt::format("# format: {}\n", kRandomTriggerFormat);
  for (const auto& [key, value] : attributes) fmt::format_to(std::back_inserter(text), "# {}: {}\n", key, value);
  text += kRandomTriggerCsvHeader;
  text += '\n';
  auto out = std::back_inserter(text);
  for (std::size_t i = 0; i < events.size(); ++i) {
    const auto hits = events.hits(i);
    if (hits.empty()) fmt::format_to(out, "{},{},,\n", events.run(i), events.event(i));
    for (const Hit& h : hits)
      fmt::format_to(out, "{},{},{},{:.17g}\n", events.run(i), events.event(i), h.counter, h.energy);
  }
  return writeOutputFile(path, text, placement);
}

// An HDF5 call on `path` that failed: what it was, and HDF5's reason.
Error hdf5Failure(const std::string& path, std::string_view what) {
  return Error{fmt::format("{}: {}: {}", path, what, detail::hdf5Reason())};
}

// The file's attributes, UTF-8 strings: its format first, then `attributes`.
Status writeAttributes(hid_t file, const std::vector<std::pair<std::string, std::string>>& attributes,
                       const std::string& path) {
  Hid stringType(H5Tcopy(H5T_C_S1), H5Tclose);
  Hid scalar(H5Screate(H5S_SCALAR), H5Sclose);
  if (!stringType.valid() || !scalar.valid() || H5Tset_size(stringType.get(), H5T_VARIABLE) < 0 ||
      H5Tset_cset(stringType.get(), H5T_CSET_UTF8) < 0) {
    return hdf5Failure(path, "cannot set up the string type of the attributes");
  }
  std::vector<std::pair<std::string, std::string>> all = {{"format", kRandomTriggerFormat}};
  all.insert(all.end(), attributes.begin(), attributes.end());
  for (const auto& [key, value] : all) {
    Hid attr(H5Acreate2(file, key.c_str(), stringType.get(), scalar.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    const char* text = value.c_str();
    if (!attr.valid() || H5Awrite(attr.get(), stringType.get(), &text) < 0) {
      return hdf5Failure(path, fmt::format("cannot write the attribute '{}'", key));
    }
  }
  return {};
}

// A group's dataset `name` of n values, with the dataset-creation properties `dcpl`.
struct Column {
  hid_t group;
  std::string_view groupName;
  hid_t dcpl;
  const std::string& path;
  Status write(const char* name, Kind kind, std::size_t n, const void* data) const {
    const hsize_t dims = n;
    const hsize_t maxDims = H5S_UNLIMITED;
    Hid space(H5Screate_simple(1, &dims, &maxDims), H5Sclose);
    Hid set(space.valid() ? H5Dcreate2(group, name, detail::fileType(kind), space.get(), H5P_DEFAULT, dcpl, H5P_DEFAULT)
                          : H5I_INVALID_HID,
            H5Dclose);
    if (!set.valid() ||
        (n > 0 && H5Dwrite(set.get(), detail::memoryType(kind), H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)) {
      return hdf5Failure(path, fmt::format("cannot write the dataset '/{}/{}'", groupName, name));
    }
    return {};
  }
};

// The events' columns: run, event, and where their hits are in the hits' columns.
Status writeEventColumns(const Column& c, const RandomTriggerEvents& events) {
  const std::size_t n = events.size();
  std::vector<std::int32_t> runs(n), counts(n);
  std::vector<std::int64_t> numbers(n), offsets(n);
  std::int64_t offset = 0;
  for (std::size_t i = 0; i < n; ++i) {
    runs[i] = events.run(i);
    numbers[i] = events.event(i);
    offsets[i] = offset;
    counts[i] = static_cast<std::int32_t>(events.hits(i).size());
    offset += counts[i];
  }
  if (Status s = c.write("run", Kind::I32, n, runs.data()); !s) return s;
  if (Status s = c.write("event", Kind::I64, n, numbers.data()); !s) return s;
  if (Status s = c.write("hit_offset", Kind::I64, n, offsets.data()); !s) return s;
  return c.write("hit_count", Kind::I32, n, counts.data());
}

// The hits' columns: counter and energy.
Status writeHitColumns(const Column& c, const RandomTriggerEvents& events) {
  const auto all_hits = events.allHits();
  std::vector<std::int32_t> counters(all_hits.size());
  std::vector<double> energies(all_hits.size());
  for (std::size_t k = 0; k < all_hits.size(); ++k) {
    counters[k] = all_hits[k].counter;
    energies[k] = all_hits[k].energy;
  }
  if (Status s = c.write("counter", Kind::I32, counters.size(), counters.data()); !s) return s;
  return c.write("energy_mev", Kind::F64, energies.size(), energies.data());
}

Status writeHdf5(const std::string& path, const RandomTriggerEvents& events,
                 const std::vector<std::pair<std::string, std::string>>& attributes, Placement placement) {
  auto out = OutputFile::reserve(path, placement);
  if (!out) return out.error();
  const std::string& tmp = (*out)->writtenPath();
  detail::Hdf5Quiet quiet;
  Hid fcpl = detail::creationList(H5P_FILE_CREATE);
  if (!fcpl.valid() || H5Pset_attr_creation_order(fcpl.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED) < 0) {
    return hdf5Failure(path, "cannot set up the file-creation properties");
  }
  Hid fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  if (!fapl.valid() || H5Pset_fclose_degree(fapl.get(), H5F_CLOSE_STRONG) < 0) {
    return hdf5Failure(path, "cannot set up the file-access properties");
  }
  Hid file(H5Fcreate(tmp.c_str(), H5F_ACC_EXCL, fcpl.get(), fapl.get()), H5Fclose);
  if (!file.valid()) return hdf5Failure(path, fmt::format("cannot create the temporary file '{}'", tmp));
  if (Status s = writeAttributes(file.get(), attributes, path); !s) return s;

  // Shuffle + deflate: every HDF5 reader (h5py without plugins) has them.
  Hid gcpl = detail::creationList(H5P_GROUP_CREATE);
  Hid dcpl = detail::creationList(H5P_DATASET_CREATE);
  const hsize_t chunk = kChunk;
  if (!gcpl.valid() || !dcpl.valid() || H5Pset_chunk(dcpl.get(), 1, &chunk) < 0 || H5Pset_shuffle(dcpl.get()) < 0 ||
      H5Pset_deflate(dcpl.get(), 4) < 0) {
    return hdf5Failure(path, "cannot set up the dataset-creation properties");
  }
  Hid group(H5Gcreate2(file.get(), kGroup, H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose);
  if (!group.valid()) return hdf5Failure(path, fmt::format("cannot create the group '/{}'", kGroup));
  if (Status s = writeEventColumns({group.get(), kGroup, dcpl.get(), path}, events); !s) return s;
  Hid hits(H5Gcreate2(file.get(), kHitsGroup, H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose);
  if (!hits.valid()) return hdf5Failure(path, fmt::format("cannot create the group '/{}'", kHitsGroup));
  if (Status s = writeHitColumns({hits.get(), kHitsGroup, dcpl.get(), path}, events); !s) return s;
  group.reset();
  hits.reset();
  if (!file.reset()) return hdf5Failure(path, "cannot close the HDF5 file");
  return (*out)->commit();
}

// ------------------------------------------------------------------------------- reading

// The columns as they travel from the reader process: the sizes, then each array.
struct Columns {
  std::vector<std::int32_t> run, count, counter;
  std::vector<std::int64_t> event, offset;
  std::vector<double> energy;
};

template <typename T>
void putArray(std::string& out, const std::vector<T>& v) {
  const std::uint64_t n = v.size();
  out.append(reinterpret_cast<const char*>(&n), sizeof n);
  out.append(reinterpret_cast<const char*>(v.data()), n * sizeof(T));
}

template <typename T>
bool takeArray(std::string_view& in, std::vector<T>& v) {
  std::uint64_t n = 0;
  if (in.size() < sizeof n) return false;
  std::memcpy(&n, in.data(), sizeof n);
  in.remove_prefix(sizeof n);
  if (n > in.size() / sizeof(T)) return false;
  v.resize(n);
  if (n > 0) std::memcpy(v.data(), in.data(), n * sizeof(T));
  in.remove_prefix(n * sizeof(T));
  return true;
}

std::string encode(const Columns& c) {
  std::string out;
  putArray(out, c.run);
  putArray(out, c.event);
  putArray(out, c.offset);
  putArray(out, c.count);
  putArray(out, c.counter);
  putArray(out, c.energy);
  return out;
}

bool decode(std::string_view in, Columns& c) {
  return takeArray(in, c.run) && takeArray(in, c.event) && takeArray(in, c.offset) && takeArray(in, c.count) &&
         takeArray(in, c.counter) && takeArray(in, c.energy) && in.empty();
}

// The string attribute `name` of the root group, or none.
std::optional<std::string> stringAttribute(hid_t file, const char* name) {
  if (H5Aexists(file, name) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return std::nullopt;
  }
  Hid attr(H5Aopen(file, name, H5P_DEFAULT), H5Aclose);
  Hid type(attr.valid() ? H5Aget_type(attr.get()) : H5I_INVALID_HID, H5Tclose);
  if (!type.valid() || H5Tget_class(type.get()) != H5T_STRING) return std::nullopt;
  Hid memType(H5Tcopy(H5T_C_S1), H5Tclose);
  if (!memType.valid() || H5Tset_cset(memType.get(), H5Tget_cset(type.get())) < 0) return std::nullopt;
  if (H5Tis_variable_str(type.get()) > 0) {
    char* text = nullptr;
    if (H5Tset_size(memType.get(), H5T_VARIABLE) < 0 || H5Aread(attr.get(), memType.get(), &text) < 0) {
      return std::nullopt;
    }
    std::string value = text != nullptr ? text : "";
    if (text != nullptr) H5free_memory(text);
    return value;
  }
  const std::size_t size = H5Tget_size(type.get());
  if (size == 0 || size > 4096) return std::nullopt;
  std::string buffer(size, '\0');
  if (H5Tset_size(memType.get(), size) < 0 || H5Tset_strpad(memType.get(), H5T_STR_NULLPAD) < 0 ||
      H5Aread(attr.get(), memType.get(), buffer.data()) < 0) {
    return std::nullopt;
  }
  return buffer.substr(0, buffer.find('\0'));
}

// Reads the whole dataset `name` of type `kind`, at most `limit` entries.
template <typename T>
Status readDataset(hid_t file, const std::string& path, const std::string& name, Kind kind, std::size_t limit,
                   std::vector<T>& out) {
  if (H5Lexists(file, name.c_str(), H5P_DEFAULT) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return Error{fmt::format("{}: the dataset '{}' is missing", path, name)};
  }
  Hid set(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose);
  Hid type(set.valid() ? H5Dget_type(set.get()) : H5I_INVALID_HID, H5Tclose);
  Hid space(set.valid() ? H5Dget_space(set.get()) : H5I_INVALID_HID, H5Sclose);
  if (!set.valid() || !type.valid() || !space.valid()) {
    return Error{fmt::format("{}: cannot open the dataset '{}': {}", path, name, detail::hdf5Reason())};
  }
  if (!detail::typeMatches(type.get(), kind)) {
    return Error{fmt::format("{}: the dataset '{}' is {}, not {}", path, name, detail::describeType(type.get()),
                             detail::kindName(kind))};
  }
  if (H5Sget_simple_extent_ndims(space.get()) != 1) {
    return Error{fmt::format("{}: the dataset '{}' is not one-dimensional", path, name)};
  }
  hsize_t n = 0;
  H5Sget_simple_extent_dims(space.get(), &n, nullptr);
  if (n > limit) {
    return Error{fmt::format("{}: the dataset '{}' has {} entries, more than the {} a random-trigger file may have",
                             path, name, n, limit)};
  }
  out.resize(n);
  if (n > 0 && H5Dread(set.get(), detail::memoryType(kind), H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0) {
    return Error{fmt::format("{}: cannot read the dataset '{}': {}", path, name, detail::hdf5Reason())};
  }
  return {};
}

// In the reader process: the raw columns, their types and lengths checked.
Result<std::string> readHdf5Columns(const std::string& path) {
  detail::Hdf5Quiet quiet;
  if (H5Fis_hdf5(path.c_str()) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    const std::string kind = describeFileAt(path);
    return Error{kind.empty() ? fmt::format("{}: not an HDF5 file (random-trigger files are HDF5 unless the name "
                                            "ends with \".csv\")",
                                            path)
                              : fmt::format("{}: this is {}, not a random-trigger file", path, kind)};
  }
  Hid file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.valid()) return Error{fmt::format("{}: cannot open the HDF5 file: {}", path, detail::hdf5Reason())};
  const bool hasFormat = H5Aexists(file.get(), "format") > 0;
  H5Eclear2(H5E_DEFAULT);
  const auto format = stringAttribute(file.get(), "format");
  if (!format || *format != kRandomTriggerFormat) {
    const bool eventFile = H5Lexists(file.get(), "/events", H5P_DEFAULT) > 0;
    H5Eclear2(H5E_DEFAULT);
    if (eventFile)
      return Error{fmt::format("{}: this is an event file (it has /events), not a random-trigger file", path)};
    return Error{
        fmt::format("{}: not a random-trigger file: its root attribute 'format' is {}, not '{}' "
                    "(docs/simulation.md, \"Recorded beam background\")",
                    path,
                    format      ? io::quotedText(*format)
                    : hasFormat ? std::string("not a string")
                                : std::string("missing"),
                    kRandomTriggerFormat)};
  }
  Columns c;
  const std::string g = std::string("/") + kGroup + "/";
  const std::string h = std::string("/") + kHitsGroup + "/";
  if (Status s = readDataset(file.get(), path, g + "run", Kind::I32, kMaxRandomTriggerEvents, c.run); !s) {
    return s.error();
  }
  if (Status s = readDataset(file.get(), path, g + "event", Kind::I64, kMaxRandomTriggerEvents, c.event); !s) {
    return s.error();
  }
  if (Status s = readDataset(file.get(), path, g + "hit_offset", Kind::I64, kMaxRandomTriggerEvents, c.offset); !s) {
    return s.error();
  }
  if (Status s = readDataset(file.get(), path, g + "hit_count", Kind::I32, kMaxRandomTriggerEvents, c.count); !s) {
    return s.error();
  }
  if (Status s = readDataset(file.get(), path, h + "counter", Kind::I32, kMaxRandomTriggerHits, c.counter); !s) {
    return s.error();
  }
  if (Status s = readDataset(file.get(), path, h + "energy_mev", Kind::F64, kMaxRandomTriggerHits, c.energy); !s) {
    return s.error();
  }
  return encode(c);
}

// The CSV columns; the offsets follow from the rows.
Result<Columns> readCsvColumns(const std::string& path) {
  auto text = readTextFile(path, kMaxCsvBytes);
  if (!text) return text.error();
  Columns c;
  std::string_view rest = *text;
  if (rest.starts_with("\xEF\xBB\xBF")) rest.remove_prefix(3);  // a UTF-8 byte-order mark
  std::size_t lineNumber = 0;
  bool header = false;
  bool lastEmpty = false;  // the current event was given as an event without hits
  while (!rest.empty()) {
    const auto end = rest.find('\n');
    if (end == std::string_view::npos) {
      return Error{fmt::format("{}: line {}: the last line has no newline (a cut file?)", path, lineNumber + 1)};
    }
    const std::string_view line = rest.substr(0, end);
    rest.remove_prefix(end + 1);
    ++lineNumber;
    if (isBlankOrComment(line)) continue;
    const auto fields = splitCsvLine(line);
    const auto at = [&](std::string_view what) { return fmt::format("{}: line {}: {}", path, lineNumber, what); };
    if (!header) {
      if (line.substr(0, line.find_last_not_of("\r ") + 1) != kRandomTriggerCsvHeader) {
        const std::string kind = describeNonJson(*text);
        return Error{kind.empty() ? at(fmt::format("the header must be '{}'", kRandomTriggerCsvHeader))
                                  : fmt::format("{}: this is {}, not a random-trigger file", path, kind)};
      }
      header = true;
      continue;
    }
    if (fields.size() != 4)
      return Error{at(fmt::format("{} fields, not 4 ({})", fields.size(), kRandomTriggerCsvHeader))};
    const auto integer = [&](std::string_view field, const char* name, auto& value) -> Status {
      const auto [p, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
      if (ec != std::errc() || p != field.data() + field.size()) {
        return Error{at(fmt::format("{} {} is not an integer", name, quotedText(field)))};
      }
      return {};
    };
    std::int32_t run = 0;
    std::int64_t event = 0;
    if (Status s = integer(fields[0], "run", run); !s) return s.error();
    if (Status s = integer(fields[1], "event", event); !s) return s.error();
    const bool sameEvent = !c.run.empty() && c.run.back() == run && c.event.back() == event;
    const bool noHit = fields[2].empty() && fields[3].empty();
    if (sameEvent && noHit && lastEmpty) {
      return Error{at(fmt::format("run {} event {} is given twice without hits", run, event))};
    }
    if (sameEvent && (noHit || lastEmpty)) {
      return Error{at(fmt::format("run {} event {} is given both without hits and with hits", run, event))};
    }
    if (!sameEvent) {
      c.run.push_back(run);
      c.event.push_back(event);
      c.offset.push_back(static_cast<std::int64_t>(c.counter.size()));
      c.count.push_back(0);
      if (c.run.size() > kMaxRandomTriggerEvents) {
        return Error{
            at(fmt::format("more than the {} events a random-trigger file may have", kMaxRandomTriggerEvents))};
      }
    }
    lastEmpty = noHit;
    if (noHit) continue;
    std::int32_t counter = 0;
    if (Status s = integer(fields[2], "counter", counter); !s) return s.error();
    const auto energy = parseFiniteDouble(fields[3]);
    if (!energy) return Error{at(fmt::format("energy_mev {} is not a finite number", quotedText(fields[3])))};
    c.counter.push_back(counter);
    c.energy.push_back(*energy);
    ++c.count.back();
    if (c.counter.size() > kMaxRandomTriggerHits) {
      return Error{at(fmt::format("more than the {} hits a random-trigger file may have", kMaxRandomTriggerHits))};
    }
  }
  if (!header) return Error{fmt::format("{}: no header line '{}' (an empty file?)", path, kRandomTriggerCsvHeader)};
  return c;
}

// The rules every file must satisfy, whatever its format.
Result<RandomTriggerEvents> checked(const std::string& path, const Columns& c, int counters, bool csv) {
  const std::size_t n = c.run.size();
  const auto record = [&](std::size_t i) {
    return csv ? fmt::format("{}: run {} event {}", path, c.run[i], c.event[i])
               : fmt::format("{}: record {} (run {}, event {})", path, i, c.run[i], c.event[i]);
  };
  if (c.event.size() != n || c.offset.size() != n || c.count.size() != n) {
    return Error{
        fmt::format("{}: the datasets of '/{}' differ in length (run {}, event {}, hit_offset {}, hit_count {})", path,
                    kGroup, n, c.event.size(), c.offset.size(), c.count.size())};
  }
  if (c.counter.size() != c.energy.size()) {
    return Error{fmt::format("{}: '/{}/counter' has {} entries, '/{}/energy_mev' {}", path, kHitsGroup,
                             c.counter.size(), kHitsGroup, c.energy.size())};
  }
  if (n == 0) return Error{fmt::format("{}: the file holds no random-trigger event", path)};
  std::vector<std::int32_t> seen(static_cast<std::size_t>(std::max(counters, 0)), -1);
  std::int64_t expected = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (c.count[i] < 0) return Error{fmt::format("{}: hit_count {} is negative", record(i), c.count[i])};
    if (c.offset[i] != expected) {
      return Error{fmt::format("{}: hit_offset {} where {} follows the previous event's hits", record(i), c.offset[i],
                               expected)};
    }
    const std::int64_t end = expected + c.count[i];
    if (end > static_cast<std::int64_t>(c.counter.size())) {
      return Error{
          fmt::format("{}: its hits end at {}, beyond the {} of '/{}'", record(i), end, c.counter.size(), kHitsGroup)};
    }
    for (auto k = static_cast<std::size_t>(expected); k < static_cast<std::size_t>(end); ++k) {
      const std::int32_t counter = c.counter[k];
      if (counter < 0 || counter >= counters) {
        return Error{fmt::format("{}: counter {} does not exist (the detector has counters 0..{})", record(i), counter,
                                 counters - 1)};
      }
      if (!(std::isfinite(c.energy[k]) && c.energy[k] >= 0.0 && c.energy[k] <= kMaxRandomTriggerEnergyMev)) {
        return Error{
            fmt::format("{}: counter {}: energy_mev {} is not an energy in [0, {:g}] MeV (a beam-background "
                        "hit; keV or eV given as MeV?)",
                        record(i), counter, c.energy[k], kMaxRandomTriggerEnergyMev)};
      }
      auto& last = seen[static_cast<std::size_t>(counter)];
      if (last == static_cast<std::int32_t>(i)) {
        return Error{fmt::format("{}: counter {} appears twice in the event", record(i), counter)};
      }
      last = static_cast<std::int32_t>(i);
    }
    expected = end;
  }
  if (expected != static_cast<std::int64_t>(c.counter.size())) {
    return Error{fmt::format("{}: '/{}' has {} hits, the events {}", path, kHitsGroup, c.counter.size(), expected)};
  }
  // Each event once.
  std::vector<std::tuple<std::int32_t, std::int64_t, std::size_t>> keys(n);
  for (std::size_t i = 0; i < n; ++i) keys[i] = {c.run[i], c.event[i], i};
  std::sort(keys.begin(), keys.end());
  for (std::size_t k = 1; k < n; ++k) {
    if (std::get<0>(keys[k]) == std::get<0>(keys[k - 1]) && std::get<1>(keys[k]) == std::get<1>(keys[k - 1])) {
      return Error{fmt::format("{}: run {} event {} appears twice ({} {} and {} of the file's events)", path,
                               std::get<0>(keys[k]), std::get<1>(keys[k]), csv ? "events" : "records",
                               std::get<2>(keys[k - 1]), std::get<2>(keys[k]))};
    }
  }
  RandomTriggerEvents events;
  events.reserve(n, c.counter.size());
  std::vector<Hit> hits;
  for (std::size_t i = 0; i < n; ++i) {
    hits.clear();
    for (std::int64_t k = c.offset[i]; k < c.offset[i] + c.count[i]; ++k) {
      hits.push_back({c.counter[static_cast<std::size_t>(k)], c.energy[static_cast<std::size_t>(k)]});
    }
    events.append(c.run[i], c.event[i], hits);
  }
  return events;
}

}  // namespace

Status writeRandomTriggerFile(const std::string& path, const RandomTriggerEvents& events,
                              const std::vector<std::pair<std::string, std::string>>& attributes, Placement placement) {
  for (const auto& [key, value] : attributes) {
    if (key.empty() || key == "format" || value.find('\n') != std::string::npos) {
      return Error{fmt::format("{}: the attribute '{}' cannot be written", path, key)};
    }
  }
  return isCsv(path) ? writeCsv(path, events, attributes, placement) : writeHdf5(path, events, attributes, placement);
}

Result<RandomTriggerEvents> readRandomTriggerFile(const std::string& path, int counters, double hdf5TimeoutSeconds) {
  protectInput({"random-trigger file", path});
  if (isCsv(path)) {
    auto columns = readCsvColumns(path);
    if (!columns) return columns.error();
    return checked(path, *columns, counters, true);
  }
  auto bytes = detail::readIsolated(
      path, [&path] { return readHdf5Columns(path); }, hdf5TimeoutSeconds);
  if (!bytes) return bytes.error();
  Columns c;
  if (!decode(*bytes, c)) {
    return Error{fmt::format("{}: the HDF5 reader process sent a malformed answer (a bug: please report it)", path)};
  }
  return checked(path, c, counters, false);
}

}  // namespace emcalign::io
