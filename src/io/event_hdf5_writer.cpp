// The HDF5 event format (docs/contract.md §6): the writer (event_hdf5_reader.cpp reads it).

#include <hdf5.h>

#include <algorithm>

#include <fmt/format.h>

#include "emcalign/io/output_file.hpp"
#include "event_file_internal.hpp"
#include "hdf5_internal.hpp"

namespace emcalign::io::detail {

namespace {

constexpr hsize_t kChunkRows = 16384;

class Hdf5Writer final : public EventWriter {
 public:
  static Result<std::unique_ptr<EventWriter>> create(const std::string& path, const WriterOptions& options) {
    auto out = OutputFile::reserve(path, options.placement);
    if (!out) return out.error();
    Hdf5Quiet quiet;
    auto w = std::unique_ptr<Hdf5Writer>(
        new Hdf5Writer(path, std::move(*out), options.withTruth, options.withHits, options.compression));
    if (auto s = w->createFile(options.attributes); !s) return s.error();
    return std::unique_ptr<EventWriter>(std::move(w));
  }

  ~Hdf5Writer() override {
    if (!state_.closed()) {
      Hdf5Quiet quiet;
      closeHandles();  // out_ then removes the temporary
    }
  }

  Status append(std::span<const ParticleRow> rows, std::span<const TruthRow> truth,
                std::span<const Hit> hits) override {
    if (auto s = usable(); !s) return s;
    if (withTruth_ && truth.size() != rows.size()) {
      return fail(fmt::format("{}: append: {} truth rows for {} rows (a file with truth needs one per row)", path_,
                              truth.size(), rows.size()));
    }
    if (auto s = checkAppend(path_, rows, hits, withHits_, appended_, consistency_); !s) return fail(s.error().message);
    Hdf5Quiet quiet;
    std::size_t hit = 0;
    for (std::size_t i = 0; i < rows.size(); ++i) {
      rows_.push_back(rows[i]);
      if (withTruth_) truth_.push_back(truth[i]);
      if (withHits_) {
        const auto n = static_cast<std::size_t>(rows[i].hitCount);
        hits_.insert(hits_.end(), hits.begin() + static_cast<std::ptrdiff_t>(hit),
                     hits.begin() + static_cast<std::ptrdiff_t>(hit + n));
        hit += n;
      }
      // Always whole chunks, whatever the append sizes: the layout depends on the rows only.
      if (rows_.size() == kChunkRows) {
        if (auto s = flush(); !s) return s;
      }
    }
    appended_ += rows.size();
    return {};
  }

  Status close() override {
    if (auto s = usable(); !s) return s;
    Hdf5Quiet quiet;
    if (auto s = flush(); !s) return s;
    if (auto why = closeHandles()) return fail(fmt::format("{}: cannot close the HDF5 file: {}", path_, *why));
    if (auto s = out_->commit(); !s) return fail(s.error().message);
    state_.close();
    return {};
  }

 private:
  Hdf5Writer(std::string path, std::unique_ptr<OutputFile> out, bool withTruth, bool withHits, Compression compression)
      : path_(std::move(path)),
        out_(std::move(out)),
        tmp_(out_->writtenPath()),
        withTruth_(withTruth),
        compression_(compression),
        withHits_(withHits) {
    rows_.reserve(kChunkRows);
    if (withTruth_) truth_.reserve(kChunkRows);
  }

  [[nodiscard]] Status usable() const { return state_.usable(); }
  Status fail(std::string message) { return state_.fail(std::move(message)); }

  Status hdf5Error(std::string_view what) { return fail(fmt::format("{}: {}: {}", path_, what, hdf5Reason())); }

  Status createFile(const Attributes& attributes) {
    if (compression_ == Compression::Lz4 && H5Zfilter_avail(kLz4Filter) <= 0) {
      H5Eclear2(H5E_DEFAULT);
      return Error{
          fmt::format("{}: HDF5 cannot load its LZ4 filter (32004), which event files are compressed with: "
                      "install Debian's hdf5-filter-plugin (scripts/install-deps does)",
                      path_)};
    }
    // The file-creation list also creates the root group: no times there either, and the
    // attributes keep the order they were given in.
    Hid fcpl = creationList(H5P_FILE_CREATE);
    if (!fcpl.valid() || H5Pset_attr_creation_order(fcpl.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED) < 0) {
      return hdf5Error("cannot set up the file-creation properties");
    }
    Hid fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
    if (!fapl.valid() || H5Pset_fclose_degree(fapl.get(), H5F_CLOSE_STRONG) < 0) {
      return hdf5Error("cannot set up the file-access properties");
    }
    // Exclusive: another writer of the same target in this process has the same temporary.
    file_ = Hid(H5Fcreate(tmp_.c_str(), H5F_ACC_EXCL, fcpl.get(), fapl.get()), H5Fclose);
    if (!file_.valid()) {
      return Error{fmt::format("{}: cannot create the temporary file '{}': {}", path_, tmp_, hdf5Reason())};
    }
    if (auto s = writeAttributes(attributes); !s) return s;

    Hid gcpl = creationList(H5P_GROUP_CREATE);
    Hid dcpl = creationList(H5P_DATASET_CREATE);
    const hsize_t chunk = kChunkRows;
    // The byte shuffle first, then the compression (the order of the filters is the order set).
    auto compress = [&] {
      return compression_ == Compression::Lz4 ? H5Pset_filter(dcpl.get(), kLz4Filter, H5Z_FLAG_MANDATORY, 0, nullptr)
                                              : H5Pset_deflate(dcpl.get(), 4);
    };
    if (!gcpl.valid() || !dcpl.valid() || H5Pset_chunk(dcpl.get(), 1, &chunk) < 0 || H5Pset_shuffle(dcpl.get()) < 0 ||
        compress() < 0) {
      return hdf5Error("cannot set up the dataset-creation properties");
    }
    events_ = Hid(H5Gcreate2(file_.get(), kEventsGroup, H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose);
    if (!events_.valid()) return hdf5Error("cannot create the group '/events'");
    for (int c = 0; c < kNumCols; ++c) {
      const std::string name(kColumnNames[static_cast<std::size_t>(c)]);
      auto ds = createDataset(events_.get(), name, eventKind(c), dcpl.get());
      if (!ds.valid()) return hdf5Error(fmt::format("cannot create the dataset '/events/{}'", name));
      eventSets_[static_cast<std::size_t>(c)] = std::move(ds);
    }
    if (withTruth_) {
      truthGroup_ = Hid(H5Gcreate2(file_.get(), kTruthGroup, H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose);
      if (!truthGroup_.valid()) return hdf5Error("cannot create the group '/truth'");
      truthSets_[0] = createDataset(truthGroup_.get(), kTruthPdg, Kind::I32, dcpl.get());
      for (std::size_t i = 0; i < kTruthDoubles.size(); ++i) {
        truthSets_[i + 1] = createDataset(truthGroup_.get(), kTruthDoubles[i].name, Kind::F64, dcpl.get());
      }
      for (const Hid& ds : truthSets_) {
        if (!ds.valid()) return hdf5Error("cannot create the datasets of '/truth'");
      }
    }
    if (withHits_) {
      hitOffsetSet_ = createDataset(events_.get(), kHitOffset, Kind::I64, dcpl.get());
      hitCountSet_ = createDataset(events_.get(), kHitCount, Kind::I32, dcpl.get());
      hitsGroup_ = Hid(H5Gcreate2(file_.get(), kHitsGroup, H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose);
      if (!hitOffsetSet_.valid() || !hitCountSet_.valid() || !hitsGroup_.valid()) {
        return hdf5Error("cannot create the hit datasets");
      }
      hitCounterSet_ = createDataset(hitsGroup_.get(), kHitCounter, Kind::I32, dcpl.get());
      hitEnergySet_ = createDataset(hitsGroup_.get(), kHitEnergy, Kind::F64, dcpl.get());
      if (!hitCounterSet_.valid() || !hitEnergySet_.valid()) return hdf5Error("cannot create the datasets of '/hits'");
    }
    return {};
  }

  static Hid createDataset(hid_t group, const std::string& name, Kind kind, hid_t dcpl) {
    const hsize_t dims = 0;
    const hsize_t maxDims = H5S_UNLIMITED;
    Hid space(H5Screate_simple(1, &dims, &maxDims), H5Sclose);
    if (!space.valid()) return {};
    return Hid(H5Dcreate2(group, name.c_str(), fileType(kind), space.get(), H5P_DEFAULT, dcpl, H5P_DEFAULT), H5Dclose);
  }

  // Variable-length UTF-8 strings, scalar, on the root group.
  Status writeAttributes(const Attributes& attributes) {
    if (attributes.empty()) return {};
    Hid type(H5Tcopy(H5T_C_S1), H5Tclose);
    Hid space(H5Screate(H5S_SCALAR), H5Sclose);
    if (!type.valid() || !space.valid() || H5Tset_size(type.get(), H5T_VARIABLE) < 0 ||
        H5Tset_cset(type.get(), H5T_CSET_UTF8) < 0) {
      return hdf5Error("cannot set up the string type of the attributes");
    }
    for (const auto& [key, value] : attributes) {
      Hid attr(H5Acreate2(file_.get(), key.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
      const char* text = value.c_str();
      if (!attr.valid() || H5Awrite(attr.get(), type.get(), &text) < 0) {
        return hdf5Error(fmt::format("cannot write the attribute '{}'", key));
      }
    }
    return {};
  }

  // Writes one column piece; on failure, HDF5's reason (taken before any other HDF5 call
  // clears the error stack, as closing the dataspaces below would).
  static std::optional<std::string> writeColumn(hid_t dataset, hsize_t offset, hsize_t count, Kind kind,
                                                const void* data) {
    const hsize_t size = offset + count;
    if (H5Dset_extent(dataset, &size) < 0) return hdf5Reason();
    Hid fileSpace(H5Dget_space(dataset), H5Sclose);
    Hid memSpace(H5Screate_simple(1, &count, nullptr), H5Sclose);
    if (!fileSpace.valid() || !memSpace.valid()) return hdf5Reason();
    if (H5Sselect_hyperslab(fileSpace.get(), H5S_SELECT_SET, &offset, nullptr, &count, nullptr) < 0) {
      return hdf5Reason();
    }
    if (H5Dwrite(dataset, memoryType(kind), memSpace.get(), fileSpace.get(), H5P_DEFAULT, data) < 0) {
      return hdf5Reason();
    }
    return std::nullopt;
  }

  Status flush() {
    if (rows_.empty()) return {};
    const hsize_t count = rows_.size();
    const auto write = [&](const Hid& ds, std::string_view group, std::string_view name, Kind kind,
                           const void* data) -> Status {
      if (auto why = writeColumn(ds.get(), written_, count, kind, data)) {
        return fail(fmt::format("{}: cannot write the dataset '/{}/{}': {}", path_, group, name, *why));
      }
      return {};
    };
    const auto gather = [&](auto&& get, auto& out) {
      out.clear();
      for (const ParticleRow& r : rows_) out.push_back(get(r));
    };
    std::vector<std::int32_t> i32;
    std::vector<std::int64_t> i64;
    std::vector<std::int8_t> i8;
    std::vector<double> f64;
    gather([](const ParticleRow& r) { return r.run; }, i32);
    if (auto s = write(eventSets_[kRun], kEventsGroup, kColumnNames[kRun], Kind::I32, i32.data()); !s) return s;
    gather([](const ParticleRow& r) { return r.event; }, i64);
    if (auto s = write(eventSets_[kEvent], kEventsGroup, kColumnNames[kEvent], Kind::I64, i64.data()); !s) {
      return s;
    }
    gather([](const ParticleRow& r) { return r.muonVeto; }, i8);
    if (auto s = write(eventSets_[kVeto], kEventsGroup, kColumnNames[kVeto], Kind::I8, i8.data()); !s) return s;
    gather([](const ParticleRow& r) { return r.charged; }, i8);
    if (auto s = write(eventSets_[kCharged], kEventsGroup, kColumnNames[kCharged], Kind::I8, i8.data()); !s) {
      return s;
    }
    for (const auto& column : kEventDoubles) {
      const auto index = static_cast<std::size_t>(std::find(kColumnNames.begin(), kColumnNames.end(), column.name) -
                                                  kColumnNames.begin());
      gather(column.get, f64);
      if (auto s = write(eventSets_[index], kEventsGroup, column.name, Kind::F64, f64.data()); !s) return s;
    }
    if (withTruth_) {
      i32.clear();
      for (const TruthRow& t : truth_) i32.push_back(t.pdg);
      if (auto s = write(truthSets_[0], kTruthGroup, kTruthPdg, Kind::I32, i32.data()); !s) return s;
      for (std::size_t i = 0; i < kTruthDoubles.size(); ++i) {
        f64.clear();
        for (const TruthRow& t : truth_) f64.push_back(kTruthDoubles[i].get(t));
        if (auto s = write(truthSets_[i + 1], kTruthGroup, kTruthDoubles[i].name, Kind::F64, f64.data()); !s) {
          return s;
        }
      }
    }
    if (withHits_) {
      i64.clear();
      i32.clear();
      std::uint64_t hitsInRows = 0;
      for (const ParticleRow& r : rows_) {
        i64.push_back(static_cast<std::int64_t>(hitsWritten_ + hitsInRows));
        i32.push_back(r.hitCount);
        hitsInRows += static_cast<std::uint64_t>(r.hitCount);
      }
      if (auto s = write(hitOffsetSet_, kEventsGroup, kHitOffset, Kind::I64, i64.data()); !s) return s;
      if (auto s = write(hitCountSet_, kEventsGroup, kHitCount, Kind::I32, i32.data()); !s) return s;
      if (auto s = flushHits(); !s) return s;
    }
    written_ += count;
    rows_.clear();
    truth_.clear();
    return {};
  }

  // The buffered hits, appended to /hits in pieces of the chunk size.
  Status flushHits() {
    for (std::size_t first = 0; first < hits_.size(); first += kChunkRows) {
      const hsize_t n = std::min<hsize_t>(kChunkRows, hits_.size() - first);
      std::vector<std::int32_t> counters(n);
      std::vector<double> energies(n);
      for (hsize_t k = 0; k < n; ++k) {
        counters[k] = hits_[first + k].counter;
        energies[k] = hits_[first + k].energy;
      }
      if (auto why = writeColumn(hitCounterSet_.get(), hitsWritten_, n, Kind::I32, counters.data())) {
        return fail(fmt::format("{}: cannot write the dataset '/{}/{}': {}", path_, kHitsGroup, kHitCounter, *why));
      }
      if (auto why = writeColumn(hitEnergySet_.get(), hitsWritten_, n, Kind::F64, energies.data())) {
        return fail(fmt::format("{}: cannot write the dataset '/{}/{}': {}", path_, kHitsGroup, kHitEnergy, *why));
      }
      hitsWritten_ += n;
    }
    hits_.clear();
    return {};
  }

  // Closes every handle (each once, whatever fails); HDF5's reason for the first failure.
  std::optional<std::string> closeHandles() {
    std::optional<std::string> why;
    const auto close = [&](Hid& h) {
      if (!h.reset() && !why) why = hdf5Reason();
    };
    for (Hid& ds : eventSets_) close(ds);
    for (Hid& ds : truthSets_) close(ds);
    for (Hid* ds : {&hitOffsetSet_, &hitCountSet_, &hitCounterSet_, &hitEnergySet_}) close(*ds);
    close(events_);
    close(truthGroup_);
    close(hitsGroup_);
    close(file_);
    return why;
  }

  std::string path_;
  std::unique_ptr<OutputFile> out_;  // destroyed uncommitted: its temporary is removed
  std::string tmp_;
  bool withTruth_;
  Compression compression_;
  Hid file_;
  Hid events_;
  Hid truthGroup_;
  std::array<Hid, kNumCols> eventSets_;
  std::array<Hid, 1 + kTruthDoubles.size()> truthSets_;
  bool withHits_;
  Hid hitsGroup_, hitOffsetSet_, hitCountSet_, hitCounterSet_, hitEnergySet_;
  std::vector<Hit> hits_;  // of the buffered rows
  std::uint64_t hitsWritten_ = 0;
  std::vector<ParticleRow> rows_;  // at most one chunk
  std::vector<TruthRow> truth_;
  hsize_t written_ = 0;
  std::uint64_t appended_ = 0;
  EventConsistency consistency_;
  WriterState state_{path_};  // after path_
};

}  // namespace

Result<std::unique_ptr<EventWriter>> openHdf5Writer(const std::string& path, const WriterOptions& options) {
  return Hdf5Writer::create(path, options);
}

}  // namespace emcalign::io::detail
