// The HDF5 event format (docs/contract.md §6): the streaming row source (event_hdf5_writer.cpp writes it).

#include <hdf5.h>

#include <algorithm>

#include <fmt/format.h>

#include "emcalign/io/file_kind.hpp"
#include "event_file_internal.hpp"
#include "hdf5_internal.hpp"

namespace emcalign::io::detail {

namespace {

// Root attributes are metadata (settings, truth parameters): a longer one is skipped.
constexpr std::size_t kMaxAttributeBytes = std::size_t{1} << 20;

// One 1-D dataset of a group, checked for type; reads ranges into a typed buffer.
struct Hdf5Column {
  Hid dataset;
  Kind kind = Kind::F64;
  std::string name;  // "/events/run"
};

class Hdf5Source final : public RowSource {
 public:
  static Result<std::unique_ptr<RowSource>> open(const std::string& path, std::size_t readRows,
                                                 const ReaderOptions& options) {
    Hdf5Quiet quiet;
    auto s = std::unique_ptr<Hdf5Source>(new Hdf5Source(path, readRows, options));
    if (auto st = s->openFile(); !st) return st.error();
    return std::unique_ptr<RowSource>(std::move(s));
  }

  Result<bool> next(ParticleRow& row, TruthRow& truth, std::vector<Hit>& hits) override {
    if (pos_ == loaded_) {
      if (first_ + loaded_ == rows_) {
        if (hasHits_ && nextHit_ != hitsTotal_) {
          return error(
              fmt::format("the rows use {} of the {} records of '/hits' (hit_offset and hit_count must "
                          "cover them all)",
                          nextHit_, hitsTotal_));
        }
        return false;
      }
      Hdf5Quiet quiet;
      if (auto s = load(first_ + loaded_); !s) return s.error();
    }
    const std::size_t i = pos_++;
    row.run = run_[i];
    row.event = event_[i];
    row.muonVeto = veto_[i];
    row.charged = charged_[i];
    for (std::size_t c = 0; c < kEventDoubles.size(); ++c) kEventDoubles[c].set(row, doubles_[c][i]);
    if (hasTruth_) {
      truth.pdg = pdg_[i];
      for (std::size_t c = 0; c < kTruthDoubles.size(); ++c) kTruthDoubles[c].set(truth, truthDoubles_[c][i]);
    }
    row.hitCount = 0;
    if (hasHits_) {
      if (auto s = takeHits(i, row, hits); !s) return s.error();
    }
    return true;
  }

  [[nodiscard]] bool hasTruth() const override { return hasTruth_; }
  [[nodiscard]] bool hasHits() const override { return hasHits_; }
  [[nodiscard]] const Attributes& attributes() const override { return attributes_; }
  [[nodiscard]] std::string location() const override {
    return fmt::format("{}: record {}", path_, first_ + pos_ - (pos_ > 0 ? 1 : 0));
  }

 private:
  Hdf5Source(std::string path, std::size_t readRows, const ReaderOptions& options)
      : path_(std::move(path)), readRows_(readRows), wantTruth_(options.truth), wantHits_(options.hits) {}

  [[nodiscard]] Error error(std::string_view what) const { return Error{fmt::format("{}: {}", path_, what)}; }

  Status openFile() {
    const htri_t isHdf5 = H5Fis_hdf5(path_.c_str());
    if (isHdf5 <= 0) {
      H5Eclear2(H5E_DEFAULT);
      const std::string kind = describeFileAt(path_);
      if (kind == kCsvEventFileKind) {
        return error(
            "this is a CSV event file: name it *.csv (event files are HDF5 unless the name ends with \".csv\")");
      }
      if (!kind.empty()) return error(fmt::format("this is {}, not an event file", kind));
      return error(
          "not an HDF5 file (no HDF5 signature; event files are HDF5 unless the name ends with "
          "\".csv\")");
    }
    file_ = Hid(H5Fopen(path_.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    if (!file_.valid()) return error(fmt::format("cannot open the HDF5 file: {}", hdf5Reason()));
    if (auto s = readAttributes(); !s) return s;
    if (linkExists("/random_trigger") && !linkExists(fmt::format("/{}", kEventsGroup))) {
      return error("this is a random-trigger file (simulate --process random-trigger), not an event file");
    }

    std::vector<std::pair<std::string, Kind>> eventColumns;
    eventColumns.reserve(kNumCols);
    for (int c = 0; c < kNumCols; ++c) {
      eventColumns.emplace_back(kColumnNames[static_cast<std::size_t>(c)], eventKind(c));
    }
    // Hits: /events/hit_offset, /events/hit_count and the group /hits, all or none.
    const bool hitOffset = linkExists(fmt::format("/{}/{}", kEventsGroup, kHitOffset));
    const bool hitCount = linkExists(fmt::format("/{}/{}", kEventsGroup, kHitCount));
    const bool hitGroup = linkExists(fmt::format("/{}", kHitsGroup));
    if (hitOffset || hitCount || hitGroup) {
      if (!(hitOffset && hitCount && hitGroup)) {
        return error(fmt::format("the hits are incomplete: '/{0}/{1}', '/{0}/{2}' and the group '/{3}' come together",
                                 kEventsGroup, kHitOffset, kHitCount, kHitsGroup));
      }
      if (wantHits_) {
        eventColumns.emplace_back(kHitOffset, Kind::I64);
        eventColumns.emplace_back(kHitCount, Kind::I32);
      }
    }
    auto events = openColumns(kEventsGroup, eventColumns, true, {kHitOffset, kHitCount});
    if (!events) return events.error();
    eventCols_ = std::move(*events);
    rows_ = rowsOf_;
    if (hitOffset && wantHits_) {
      auto hits = openColumns(kHitsGroup, {{kHitCounter, Kind::I32}, {kHitEnergy, Kind::F64}}, true);
      if (!hits) return hits.error();
      hitCols_ = std::move(*hits);
      hitsTotal_ = rowsOf_;
      hasHits_ = true;
    }

    if (!wantTruth_) return {};
    std::vector<std::pair<std::string, Kind>> truthColumns{{kTruthPdg, Kind::I32}};
    for (const auto& column : kTruthDoubles) truthColumns.emplace_back(column.name, Kind::F64);
    auto truth = openColumns(kTruthGroup, truthColumns, false);
    if (!truth) return truth.error();
    truthCols_ = std::move(*truth);
    hasTruth_ = !truthCols_.empty();
    if (hasTruth_ && rowsOf_ != rows_) {
      return error(fmt::format("the datasets of '/truth' have {} records, those of '/events' {}", rowsOf_, rows_));
    }
    return {};
  }
  [[nodiscard]] bool linkExists(const std::string& path) const {
    const htri_t e = H5Lexists(file_.get(), path.c_str(), H5P_DEFAULT);
    if (e < 0) H5Eclear2(H5E_DEFAULT);
    return e > 0;
  }

  // Appends the hits of loaded row i (checked to follow the previous row's) to `out`.
  Status takeHits(std::size_t i, ParticleRow& row, std::vector<Hit>& out) {
    const std::int64_t offset = hitOffset_[i];
    const std::int32_t count = hitCount_[i];
    if (offset < 0 || static_cast<hsize_t>(offset) != nextHit_) {
      return error(fmt::format("record {}: column '{}': {}, expected {} (the rows' hits follow each other from 0)",
                               first_ + i, kHitOffset, offset, nextHit_));
    }
    if (count < 0 || count > kMaxHitsPerRow || static_cast<hsize_t>(count) > hitsTotal_ - nextHit_) {
      return error(fmt::format("record {}: column '{}': {} is outside [0, {}] or beyond the {} records of '/hits'",
                               first_ + i, kHitCount, count, kMaxHitsPerRow, hitsTotal_));
    }
    const hsize_t begin = nextHit_, end = nextHit_ + static_cast<hsize_t>(count);
    if (begin < windowFirst_ || end > windowFirst_ + windowCounter_.size()) {
      // A window of /hits from `begin`: bounded memory whatever the block size.
      constexpr hsize_t kWindow = hsize_t{1} << 18;
      const hsize_t n = std::min<hsize_t>(std::max<hsize_t>(kWindow, end - begin), hitsTotal_ - begin);
      windowCounter_.resize(n);
      windowEnergy_.resize(n);
      Hdf5Quiet quiet;
      if (!readRange(hitCols_[0], begin, n, windowCounter_.data()) ||
          !readRange(hitCols_[1], begin, n, windowEnergy_.data())) {
        return error(
            fmt::format("records {}..{} of '/{}': cannot read: {}", begin, begin + n - 1, kHitsGroup, hdf5Reason()));
      }
      windowFirst_ = begin;
    }
    for (hsize_t k = begin; k < end; ++k) {
      out.push_back({windowCounter_[k - windowFirst_], windowEnergy_[k - windowFirst_]});
    }
    row.hitCount = count;
    nextHit_ = end;
    return {};
  }

  // Opens every listed dataset of a group (all required), checking names, types, rank and
  // equal lengths; an absent optional group gives no columns. `skipped` names links that
  // may be there but are not read. Sets rowsOf_.
  Result<std::vector<Hdf5Column>> openColumns(const char* groupName,
                                              const std::vector<std::pair<std::string, Kind>>& columns, bool required,
                                              std::initializer_list<std::string_view> skipped = {}) {
    const htri_t exists = H5Lexists(file_.get(), groupName, H5P_DEFAULT);
    if (exists <= 0) {
      H5Eclear2(H5E_DEFAULT);
      if (!required) return std::vector<Hdf5Column>{};
      return error(fmt::format("missing group '/{}' (not an emcalign event file?)", groupName));
    }
    Hid group(H5Gopen2(file_.get(), groupName, H5P_DEFAULT), H5Gclose);
    if (!group.valid()) return error(fmt::format("'/{}' is not a group: {}", groupName, hdf5Reason()));

    // Every link of the group must be a known column.
    std::vector<std::string> links;
    hsize_t index = 0;
    const herr_t iterated = H5Literate(
        group.get(), H5_INDEX_NAME, H5_ITER_INC, &index,
        [](hid_t, const char* name, const H5L_info_t*, void* data) -> herr_t {
          static_cast<std::vector<std::string>*>(data)->emplace_back(name);
          return 0;
        },
        &links);
    if (iterated < 0) return error(fmt::format("cannot list '/{}': {}", groupName, hdf5Reason()));
    for (const std::string& link : links) {
      bool known = std::find(skipped.begin(), skipped.end(), link) != skipped.end();
      for (const auto& column : columns) known = known || column.first == link;
      if (!known) return error(fmt::format("unexpected dataset '/{}/{}'", groupName, link));
    }

    std::vector<Hdf5Column> out;
    for (const auto& [name, kind] : columns) {
      Hdf5Column column{{}, kind, fmt::format("/{}/{}", groupName, name)};
      if (H5Lexists(group.get(), name.c_str(), H5P_DEFAULT) <= 0) {
        H5Eclear2(H5E_DEFAULT);
        return error(fmt::format("missing dataset '{}' (column '{}')", column.name, name));
      }
      column.dataset = Hid(H5Dopen2(group.get(), name.c_str(), H5P_DEFAULT), H5Dclose);
      if (!column.dataset.valid()) {
        return error(fmt::format("'{}' is not a dataset: {}", column.name, hdf5Reason()));
      }
      Hid type(H5Dget_type(column.dataset.get()), H5Tclose);
      if (!type.valid()) return error(fmt::format("dataset '{}': {}", column.name, hdf5Reason()));
      if (!typeMatches(type.get(), kind)) {
        return error(fmt::format("dataset '{}' (column '{}'): type is {}, expected {}", column.name, name,
                                 describeType(type.get()), kindName(kind)));
      }
      Hid space(H5Dget_space(column.dataset.get()), H5Sclose);
      hsize_t dims = 0;
      if (!space.valid() || H5Sget_simple_extent_ndims(space.get()) != 1 ||
          H5Sget_simple_extent_dims(space.get(), &dims, nullptr) != 1) {
        H5Eclear2(H5E_DEFAULT);
        return error(fmt::format("dataset '{}' (column '{}'): not one-dimensional", column.name, name));
      }
      if (!out.empty() && dims != rowsOf_) {
        return error(
            fmt::format("dataset '{}' (column '{}') has {} records, '{}' has {} (datasets of "
                        "unequal length: truncated or inconsistent file)",
                        column.name, name, dims, out.front().name, rowsOf_));
      }
      rowsOf_ = dims;
      out.push_back(std::move(column));
    }
    return out;
  }

  // String attributes of the root group, in creation order when the file tracks it;
  // attributes of other types are skipped.
  Status readAttributes() {
    Hid root(H5Gopen2(file_.get(), "/", H5P_DEFAULT), H5Gclose);
    if (!root.valid()) return error(fmt::format("cannot open the root group: {}", hdf5Reason()));
    std::vector<std::string> names;
    const auto collect = [](hid_t, const char* name, const H5A_info_t*, void* data) -> herr_t {
      static_cast<std::vector<std::string>*>(data)->emplace_back(name);
      return 0;
    };
    hsize_t index = 0;
    if (H5Aiterate2(root.get(), H5_INDEX_CRT_ORDER, H5_ITER_INC, &index, collect, &names) < 0) {
      H5Eclear2(H5E_DEFAULT);
      names.clear();
      index = 0;
      if (H5Aiterate2(root.get(), H5_INDEX_NAME, H5_ITER_INC, &index, collect, &names) < 0) {
        return error(fmt::format("cannot list the attributes: {}", hdf5Reason()));
      }
    }
    for (const std::string& name : names) {
      Hid attr(H5Aopen(root.get(), name.c_str(), H5P_DEFAULT), H5Aclose);
      Hid type(attr.valid() ? H5Aget_type(attr.get()) : H5I_INVALID_HID, H5Tclose);
      Hid space(attr.valid() ? H5Aget_space(attr.get()) : H5I_INVALID_HID, H5Sclose);
      if (!attr.valid() || !type.valid() || !space.valid()) {
        return error(fmt::format("cannot open the attribute '{}': {}", name, hdf5Reason()));
      }
      if (H5Tget_class(type.get()) != H5T_STRING || H5Sget_simple_extent_npoints(space.get()) != 1) continue;
      Hid memType(H5Tcopy(H5T_C_S1), H5Tclose);
      std::string value;
      bool ok = memType.valid() && H5Tset_cset(memType.get(), H5Tget_cset(type.get())) >= 0;
      if (ok && H5Tis_variable_str(type.get()) > 0) {
        char* text = nullptr;
        ok = H5Tset_size(memType.get(), H5T_VARIABLE) >= 0 && H5Aread(attr.get(), memType.get(), &text) >= 0;
        if (ok && text != nullptr) value = text;
        if (text != nullptr) H5free_memory(text);
      } else if (ok) {
        const std::size_t size = H5Tget_size(type.get());
        if (size == 0 || size > kMaxAttributeBytes) continue;  // not metadata emcalign writes
        std::string buffer(size, '\0');
        ok = H5Tset_size(memType.get(), size) >= 0 && H5Tset_strpad(memType.get(), H5T_STR_NULLPAD) >= 0 &&
             H5Aread(attr.get(), memType.get(), buffer.data()) >= 0;
        value = buffer.substr(0, buffer.find('\0'));
      }
      if (!ok) return error(fmt::format("cannot read the attribute '{}': {}", name, hdf5Reason()));
      if (value.size() > kMaxAttributeBytes) continue;
      attributes_.emplace_back(name, std::move(value));
    }
    return {};
  }

  static bool readRange(const Hdf5Column& column, hsize_t offset, hsize_t count, void* out) {
    Hid fileSpace(H5Dget_space(column.dataset.get()), H5Sclose);
    Hid memSpace(H5Screate_simple(1, &count, nullptr), H5Sclose);
    if (!fileSpace.valid() || !memSpace.valid()) return false;
    if (H5Sselect_hyperslab(fileSpace.get(), H5S_SELECT_SET, &offset, nullptr, &count, nullptr) < 0) {
      return false;
    }
    return H5Dread(column.dataset.get(), memoryType(column.kind), memSpace.get(), fileSpace.get(), H5P_DEFAULT, out) >=
           0;
  }

  Status load(hsize_t offset) {
    const hsize_t count = std::min<hsize_t>(readRows_, rows_ - offset);
    const auto read = [&](const Hdf5Column& column, auto& buffer) -> Status {
      buffer.resize(count);
      if (!readRange(column, offset, count, buffer.data())) {
        return error(fmt::format("records {}..{}: cannot read dataset '{}': {}", offset, offset + count - 1,
                                 column.name, hdf5Reason()));
      }
      return {};
    };
    if (auto s = read(eventCols_[kRun], run_); !s) return s;
    if (auto s = read(eventCols_[kEvent], event_); !s) return s;
    if (auto s = read(eventCols_[kVeto], veto_); !s) return s;
    if (auto s = read(eventCols_[kCharged], charged_); !s) return s;
    for (std::size_t c = 0; c < kEventDoubles.size(); ++c) {
      const auto index = static_cast<std::size_t>(
          std::find(kColumnNames.begin(), kColumnNames.end(), kEventDoubles[c].name) - kColumnNames.begin());
      if (auto s = read(eventCols_[index], doubles_[c]); !s) return s;
    }
    if (hasTruth_) {
      if (auto s = read(truthCols_[0], pdg_); !s) return s;
      for (std::size_t c = 0; c < kTruthDoubles.size(); ++c) {
        if (auto s = read(truthCols_[c + 1], truthDoubles_[c]); !s) return s;
      }
    }
    if (hasHits_) {
      if (auto s = read(eventCols_[kNumCols], hitOffset_); !s) return s;
      if (auto s = read(eventCols_[kNumCols + 1], hitCount_); !s) return s;
    }
    first_ = offset;
    loaded_ = count;
    pos_ = 0;
    return {};
  }

  std::string path_;
  hsize_t readRows_;
  bool wantTruth_ = true;
  bool wantHits_ = true;
  Hid file_;
  Attributes attributes_;
  std::vector<Hdf5Column> eventCols_;
  std::vector<Hdf5Column> truthCols_;
  bool hasTruth_ = false;
  hsize_t rowsOf_ = 0;  // length found by the last openColumns
  hsize_t rows_ = 0;
  // The loaded range [first_, first_ + loaded_) and the next row in it.
  hsize_t first_ = 0;
  hsize_t loaded_ = 0;
  hsize_t pos_ = 0;
  std::vector<std::int32_t> run_;
  std::vector<std::int64_t> event_;
  std::vector<std::int8_t> veto_;
  std::vector<std::int8_t> charged_;
  std::array<std::vector<double>, kEventDoubles.size()> doubles_;
  std::vector<std::int32_t> pdg_;
  std::array<std::vector<double>, kTruthDoubles.size()> truthDoubles_;
  // Hits: the per-row offsets and counts of the loaded rows, and a window of /hits.
  bool hasHits_ = false;
  std::vector<Hdf5Column> hitCols_;
  hsize_t hitsTotal_ = 0;
  hsize_t nextHit_ = 0;  // where the next row's hits must start
  std::vector<std::int64_t> hitOffset_;
  std::vector<std::int32_t> hitCount_;
  hsize_t windowFirst_ = 0;
  std::vector<std::int32_t> windowCounter_;
  std::vector<double> windowEnergy_;
};

}  // namespace

Result<std::unique_ptr<RowSource>> openHdf5Source(const std::string& path, std::size_t readRows,
                                                  const ReaderOptions& options) {
  return Hdf5Source::open(path, readRows, options);
}

}  // namespace emcalign::io::detail
