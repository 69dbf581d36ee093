#include "osm_graph_slam/osm/osm_reader.h"

#include <bzlib.h>
#include <zlib.h>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <functional>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <osmium/area/assembler.hpp>
#include <osmium/io/any_input.hpp>
#include <osmium/memory/buffer.hpp>
#include <osmium/osm.hpp>
#include <protozero/pbf_reader.hpp>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

namespace osm_graph_slam {
namespace {

/// Thrown inside a pass when an OsmReadOptions limit is exceeded.
struct LimitExceeded : std::runtime_error {
  using std::runtime_error::runtime_error;
};

bool isBuildingRelation(const osmium::Relation& relation) {
  const char* type = relation.tags()["type"];
  return type && std::strcmp(type, "multipolygon") == 0 && relation.tags().has_key("building");
}

OsmTags copyTags(const osmium::TagList& tags) {
  OsmTags out;
  for (const osmium::Tag& tag : tags) out.emplace(tag.key(), tag.value());
  return out;
}

/// Ring of locations -> outline without the repeated closing vertex and without consecutive
/// duplicates. Returns false if fewer than 3 distinct vertices remain.
bool ringToOutline(const osmium::NodeRefList& ring, std::vector<GeoPoint>& outline) {
  outline.clear();
  for (const osmium::NodeRef& node : ring) {
    const GeoPoint p{node.location().lat(), node.location().lon()};
    if (!outline.empty() && outline.back().lat == p.lat && outline.back().lon == p.lon) continue;
    outline.push_back(p);
  }
  while (outline.size() > 1 && outline.front().lat == outline.back().lat &&
         outline.front().lon == outline.back().lon) {
    outline.pop_back();
  }
  return outline.size() >= 3;
}

bool allLocationsValid(const osmium::Way& way) {
  for (const osmium::NodeRef& node : way.nodes()) {
    if (!node.location().valid()) return false;
  }
  return !way.nodes().empty();
}

struct XmlErrorPosition {
  bool valid = false;
  uint64_t line = 0;
  uint64_t column = 0;
};

std::string describeException(const std::exception& e) {
  std::ostringstream msg;
  if (const auto* xml = dynamic_cast<const osmium::xml_error*>(&e)) {
    msg << "malformed OSM XML at line " << xml->line << ", column " << xml->column << ": "
        << xml->error_string;
  } else if (dynamic_cast<const osmium::pbf_error*>(&e)) {
    msg << "malformed OSM PBF: " << e.what();
  } else if (dynamic_cast<const LimitExceeded*>(&e)) {
    msg << "input too large: " << e.what();
  } else {
    msg << "cannot read OSM data: " << e.what();
  }
  return msg.str();
}

/// Finds coordinate attributes (lat, lon, minlat, maxlon...) that libosmium 2.19's
/// string_to_location_coordinate would overflow a signed 64-bit integer on (undefined behaviour,
/// found by fuzz_osm_xml, issue 22): an exponent ("1e99") or a character reference that expat
/// would decode into one ("1&#101;99"). OSM writers never produce either, so such a document is
/// refused at that attribute (and what precedes it salvaged) instead of being handed to libosmium.
/// A small XML tokenizer: only attribute values inside tags count, comments, CDATA sections and
/// text are skipped. Feed the document in pieces of any size.
class UnsafeCoordinateScanner {
 public:
  /// Returns false once an unsafe coordinate was seen (then line(), offset(), value() say where).
  bool feed(const char* data, size_t size) {
    for (size_t i = 0; i < size && !found_; ++i) step(data[i]);
    return !found_;
  }
  bool found() const { return found_; }
  uint64_t line() const { return found_line_; }
  uint64_t offset() const { return found_offset_; }  ///< byte offset of the attribute value
  const std::string& value() const { return value_; }

 private:
  enum class State { kText, kTag, kValue, kSkip };

  static bool isNameChar(char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == ':' || c == '-' ||
           c == '.';
  }
  static bool endsWith(const std::string& s, const char* suffix) {
    const size_t n = std::strlen(suffix);
    return s.size() >= n && s.compare(s.size() - n, n, suffix) == 0;
  }

  void step(char c) {
    recent_ = (recent_ << 8) | static_cast<unsigned char>(c);
    switch (state_) {
      case State::kText:
        if (c == '<') {
          state_ = State::kTag;
          name_.clear();
          name_done_ = false;
          pending_coordinate_ = false;
          cdata_candidate_ = false;
          tag_chars_ = 0;
        }
        break;
      case State::kTag:
        ++tag_chars_;
        // tag_chars_ counts the characters after '<'.
        if (tag_chars_ == 2 && (recent_ & 0xffffff) == 0x3c212d) {  // "<!-"
          state_ = State::kSkip;
          terminator_ = "-->";
        } else if (tag_chars_ == 1 && (recent_ & 0xffff) == 0x3c21) {  // "<!": maybe CDATA
          cdata_candidate_ = true;
        } else if (cdata_candidate_ && tag_chars_ == 7) {
          cdata_candidate_ = false;
          if ((recent_ & 0xffffffffffffULL) == 0x5b4344415441ULL) {  // "[CDATA"
            state_ = State::kSkip;
            terminator_ = "]]>";
          }
        }
        if (state_ == State::kSkip) {
          matched_ = 0;
        } else if (c == '>') {
          state_ = State::kText;
        } else if (c == '"' || c == '\'') {
          quote_ = c;
          state_ = State::kValue;
          coordinate_ = pending_coordinate_;
          pending_coordinate_ = false;
          value_start_ = offset_ + 1;
          value_.clear();
        } else if (c == '=') {
          pending_coordinate_ = endsWith(name_, "lat") || endsWith(name_, "lon");
          name_.clear();
        } else if (isNameChar(c)) {
          if (name_done_) name_.clear();
          name_done_ = false;
          name_ += c;
          if (name_.size() > 64) name_.erase(0, name_.size() - 64);
        } else {
          name_done_ = !name_.empty();
        }
        break;
      case State::kValue:
        if (c == quote_) {
          state_ = State::kTag;
          name_.clear();
        } else if (coordinate_) {
          if (value_.size() < 40) value_ += c;
          if (c == 'e' || c == 'E' || c == '&') {
            found_ = true;
            found_line_ = line_;
            found_offset_ = value_start_;
          }
        }
        break;
      case State::kSkip:
        // Both terminators are "XX>": a third X keeps two matched.
        if (c == terminator_[matched_]) {
          ++matched_;
        } else {
          matched_ = c == terminator_[0] ? (matched_ == 2 ? 2 : 1) : 0;
        }
        if (terminator_[matched_] == '\0') state_ = State::kText;
        break;
    }
    if (c == '\n') ++line_;
    ++offset_;
  }

  State state_ = State::kText;
  std::string name_;
  bool name_done_ = false;
  bool pending_coordinate_ = false;
  bool coordinate_ = false;
  bool cdata_candidate_ = false;
  int tag_chars_ = 0;
  char quote_ = '"';
  const char* terminator_ = "";
  size_t matched_ = 0;
  uint64_t recent_ = 0;
  uint64_t line_ = 1;
  uint64_t offset_ = 0;
  uint64_t value_start_ = 0;
  bool found_ = false;
  uint64_t found_line_ = 0;
  uint64_t found_offset_ = 0;
  std::string value_;
};

/// Walks the BlobHeaders of a PBF file (only the headers are read; the blobs are skipped). A
/// header without its `type` string made libosmium 2.19 call strncmp with a null pointer
/// (undefined behaviour, found by fuzz_osm_file), so such a file is refused here with the blob
/// named. Anything else malformed is left for libosmium to report. Returns "" when fine.
std::string checkPbfBlobHeaders(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string header;
  for (size_t blob = 0; in; ++blob) {
    unsigned char size_bytes[4];
    in.read(reinterpret_cast<char*>(size_bytes), 4);
    if (in.gcount() != 4) return "";  // end of file (or a truncation libosmium reports)
    const uint32_t size = (uint32_t{size_bytes[0]} << 24) | (uint32_t{size_bytes[1]} << 16) |
                          (uint32_t{size_bytes[2]} << 8) | uint32_t{size_bytes[3]};
    if (size == 0 || size > 64 * 1024) return "";  // libosmium refuses these itself
    header.resize(size);
    if (!in.read(header.data(), size)) return "";
    bool has_type = false;
    int64_t data_size = 0;
    try {
      protozero::pbf_reader message{header.data(), header.size()};
      while (message.next()) {
        if (message.tag() == 1 &&
            message.wire_type() == protozero::pbf_wire_type::length_delimited) {
          has_type = message.get_view().size() > 0;
        } else if (message.tag() == 3 && message.wire_type() == protozero::pbf_wire_type::varint) {
          data_size = message.get_int32();
        } else {
          message.skip();
        }
      }
    } catch (const std::exception&) {
      return "";  // libosmium decodes the same header and reports the error
    }
    if (!has_type) {
      return "malformed OSM PBF: blob header " + std::to_string(blob) + " has no type";
    }
    if (data_size <= 0) return "";
    in.seekg(data_size, std::ios::cur);
  }
  return "";
}

std::string unsafeCoordinateError(const UnsafeCoordinateScanner& scanner) {
  return "malformed OSM XML at line " + std::to_string(scanner.line()) + ": coordinate '" +
         scanner.value() +
         "...' in exponent notation or with a character reference (not read: libosmium's "
         "coordinate parser overflows on it)";
}

/// Three passes over the input so that only what is needed stays in memory:
/// relations (building multipolygons) -> ways (buildings, roads, relation members) -> the
/// locations of the nodes those ways reference. A pass that fails records the first error and
/// the data read before the failure is still assembled.
class OsmCollector {
 public:
  OsmCollector(const OsmReadOptions& options, OsmData& out, XmlErrorPosition* error_position)
      : options_(options), out_(out), error_position_(error_position) {}

  void run(const osmium::io::File& file) {
    pass(file, osmium::osm_entity_bits::relation,
         [this](const osmium::memory::Buffer& b) { collectRelations(b); });
    std::sort(member_way_ids_.begin(), member_way_ids_.end());
    member_way_ids_.erase(std::unique(member_way_ids_.begin(), member_way_ids_.end()),
                          member_way_ids_.end());
    pass(file, osmium::osm_entity_bits::way,
         [this](const osmium::memory::Buffer& b) { collectWays(b); });
    std::sort(node_ids_.begin(), node_ids_.end());
    node_ids_.erase(std::unique(node_ids_.begin(), node_ids_.end()), node_ids_.end());
    node_locations_.assign(node_ids_.size(), osmium::Location{});
    pass(file, osmium::osm_entity_bits::node,
         [this](const osmium::memory::Buffer& b) { collectNodes(b); });
    attachLocations();
    buildWays();
    buildRelations();
    out_.stats.buildings = out_.buildings.size();
    out_.stats.roads = out_.roads.size();
    out_.ok = error_.empty();
    out_.error = error_;
  }

 private:
  struct WayEntry {
    size_t offset;
    bool building;
    bool road;
  };

  template <typename F>
  void pass(const osmium::io::File& file, osmium::osm_entity_bits::type bits, F&& on_buffer) {
    try {
      osmium::io::Reader reader{file, bits, osmium::io::read_meta::no};
      while (osmium::memory::Buffer buffer = reader.read()) on_buffer(buffer);
      reader.close();
    } catch (const std::exception& e) {
      if (!error_.empty()) return;
      error_ = describeException(e);
      const auto* xml = dynamic_cast<const osmium::xml_error*>(&e);
      if (xml && error_position_) *error_position_ = {true, xml->line, xml->column};
    }
  }

  void checkObjectLimit() const {
    if (relation_offsets_.size() + way_entries_.size() > options_.max_objects) {
      throw LimitExceeded("more than " + std::to_string(options_.max_objects) +
                          " relevant ways/relations");
    }
  }

  void collectRelations(const osmium::memory::Buffer& buffer) {
    for (const auto& relation : buffer.select<osmium::Relation>()) {
      ++out_.stats.relations_seen;
      if (!isBuildingRelation(relation)) continue;
      checkObjectLimit();
      relation_offsets_.push_back(relations_.committed());
      relations_.add_item(relation);
      relations_.commit();
      for (const auto& member : relation.members()) {
        if (member.type() == osmium::item_type::way) member_way_ids_.push_back(member.ref());
      }
    }
  }

  void collectWays(const osmium::memory::Buffer& buffer) {
    for (const auto& way : buffer.select<osmium::Way>()) {
      ++out_.stats.ways_seen;
      const bool building = way.tags().has_key("building");
      const bool road = options_.read_roads && way.tags().has_key("highway");
      const bool member =
          std::binary_search(member_way_ids_.begin(), member_way_ids_.end(), way.id());
      if (!building && !road && !member) continue;
      if (way_offset_by_id_.count(way.id())) continue;  // duplicate id in a broken file
      checkObjectLimit();
      way_offset_by_id_.emplace(way.id(), ways_.committed());
      way_entries_.push_back({ways_.committed(), building, road});
      ways_.add_item(way);
      ways_.commit();
      for (const auto& node : way.nodes()) node_ids_.push_back(node.ref());
      if (node_ids_.size() > options_.max_nodes) {
        throw LimitExceeded("more than " + std::to_string(options_.max_nodes) +
                            " referenced nodes");
      }
    }
  }

  void collectNodes(const osmium::memory::Buffer& buffer) {
    for (const auto& node : buffer.select<osmium::Node>()) {
      const auto it = std::lower_bound(node_ids_.begin(), node_ids_.end(), node.id());
      if (it == node_ids_.end() || *it != node.id()) continue;
      if (node.location().valid()) node_locations_[it - node_ids_.begin()] = node.location();
    }
  }

  void attachLocations() {
    for (auto& way : ways_.select<osmium::Way>()) {
      for (auto& node : way.nodes()) {
        const auto it = std::lower_bound(node_ids_.begin(), node_ids_.end(), node.ref());
        if (it != node_ids_.end() && *it == node.ref()) {
          node.set_location(node_locations_[it - node_ids_.begin()]);
        }
      }
    }
  }

  void buildWays() {
    for (const WayEntry& entry : way_entries_) {
      const auto& way = ways_.get<osmium::Way>(entry.offset);
      if (!entry.building && !entry.road) continue;  // only a relation member
      if (!allLocationsValid(way)) {
        ++out_.stats.skipped_missing_nodes;
        continue;
      }
      if (entry.building) addBuildingWay(way);
      if (entry.road) addRoad(way);
    }
  }

  void addBuildingWay(const osmium::Way& way) {
    const auto& nodes = way.nodes();
    if (!nodes.ends_have_same_id() && nodes.front().location() != nodes.back().location()) {
      ++out_.stats.skipped_open;
      return;
    }
    Building building;
    building.id = way.id();
    building.version = static_cast<int>(way.version());
    building.tags = copyTags(way.tags());
    if (!ringToOutline(nodes, building.outline_geo)) {
      ++out_.stats.skipped_degenerate;
      return;
    }
    out_.buildings.push_back(std::move(building));
  }

  void addRoad(const osmium::Way& way) {
    Road road;
    road.id = way.id();
    road.tags = copyTags(way.tags());
    road.highway = way.tags()["highway"];
    for (const auto& node : way.nodes()) {
      road.nodes_geo.push_back({node.location().lat(), node.location().lon()});
    }
    out_.roads.push_back(std::move(road));
  }

  void buildRelations() {
    osmium::area::AssemblerConfig config;
    config.create_empty_areas = false;
    for (const size_t offset : relation_offsets_) {
      const auto& relation = relations_.get<osmium::Relation>(offset);
      std::vector<const osmium::Way*> members;
      if (!collectMembers(relation, members)) {
        ++out_.stats.skipped_relations;
        continue;
      }
      osmium::memory::Buffer area_buffer{4096, osmium::memory::Buffer::auto_grow::yes};
      osmium::area::Assembler assembler{config};
      if (!assembler(relation, members, area_buffer)) {
        ++out_.stats.skipped_relations;
        continue;
      }
      for (const auto& area : area_buffer.select<osmium::Area>()) addRelationParts(relation, area);
    }
  }

  bool collectMembers(const osmium::Relation& relation, std::vector<const osmium::Way*>& members) {
    for (const auto& member : relation.members()) {
      if (member.type() != osmium::item_type::way) continue;
      const auto it = way_offset_by_id_.find(member.ref());
      if (it == way_offset_by_id_.end()) return false;
      const auto& way = ways_.get<osmium::Way>(it->second);
      if (!allLocationsValid(way)) return false;
      members.push_back(&way);
    }
    return !members.empty();
  }

  void addRelationParts(const osmium::Relation& relation, const osmium::Area& area) {
    int part = 0;
    for (const auto& ring : area.outer_rings()) {
      Building building;
      building.id = -relation.id();
      building.part = part;
      building.tags = copyTags(relation.tags());
      if (!ringToOutline(ring, building.outline_geo)) {
        ++out_.stats.skipped_degenerate;
        continue;
      }
      out_.buildings.push_back(std::move(building));
      ++part;
    }
  }

  OsmReadOptions options_;
  OsmData& out_;
  XmlErrorPosition* error_position_;
  std::string error_;

  osmium::memory::Buffer relations_{64 * 1024, osmium::memory::Buffer::auto_grow::yes};
  std::vector<size_t> relation_offsets_;
  std::vector<osmium::object_id_type> member_way_ids_;

  osmium::memory::Buffer ways_{1024 * 1024, osmium::memory::Buffer::auto_grow::yes};
  std::vector<WayEntry> way_entries_;
  std::unordered_map<osmium::object_id_type, size_t> way_offset_by_id_;

  std::vector<osmium::object_id_type> node_ids_;  // sorted, unique after the way pass
  std::vector<osmium::Location> node_locations_;
};

OsmData readWithCollector(const std::function<osmium::io::File()>& make_file,
                          const OsmReadOptions& options,
                          XmlErrorPosition* error_position = nullptr) {
  OsmData data;
  try {
    OsmCollector collector(options, data, error_position);
    collector.run(make_file());
  } catch (const std::exception& e) {
    data.ok = false;
    data.error = describeException(e);
  } catch (...) {
    data.ok = false;
    data.error = "cannot read OSM data: unknown error";
  }
  return data;
}

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

OsmData salvageXmlFile(const std::string& path, const OsmReadOptions& options, OsmData data);

/// A read-only mapping of a whole file. libosmium 2.19's Reader leaks the file descriptor of every
/// file whose parsing fails (PBF, gzip, bzip2; one per failed pass: a process reading bad files
/// runs out of descriptors, found by fuzzing). Parsing from the mapping gives libosmium no
/// descriptor at all, and the reader's three passes share one mapping.
class MappedFile {
 public:
  explicit MappedFile(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
      error_ = std::strerror(errno);
      return;
    }
    struct stat st {};
    if (::fstat(fd, &st) != 0) {
      error_ = std::strerror(errno);
    } else if (st.st_size == 0) {
      error_ = "the file is empty";
    } else {
      void* data = ::mmap(nullptr, static_cast<size_t>(st.st_size), PROT_READ, MAP_PRIVATE, fd, 0);
      if (data == MAP_FAILED) {
        error_ = std::strerror(errno);
      } else {
        data_ = static_cast<const char*>(data);
        size_ = static_cast<size_t>(st.st_size);
      }
    }
    ::close(fd);  // the mapping stays valid without it
  }
  ~MappedFile() {
    if (data_) ::munmap(const_cast<char*>(data_), size_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  const char* data() const { return data_; }
  size_t size() const { return size_; }
  const std::string& error() const { return error_; }

 private:
  const char* data_ = nullptr;
  size_t size_ = 0;
  std::string error_;
};

/// libosmium's format string for a buffer holding a file with this (known) suffix.
std::string bufferFormat(const std::string& path) {
  if (endsWith(path, ".pbf")) return "pbf";
  if (endsWith(path, ".osm.gz")) return "osm.gz";
  if (endsWith(path, ".osm.bz2")) return "osm.bz2";
  return "osm";  // .osm, .xml
}

}  // namespace

OsmData readOsmFile(const std::string& path, const OsmReadOptions& options) {
  // Only formats a map file can sensibly have; libosmium picks the codec from the suffix.
  static const char* const kSuffixes[] = {".osm",    ".osm.pbf", ".pbf",
                                          ".osm.gz", ".osm.bz2", ".xml"};
  bool known = false;
  for (const char* suffix : kSuffixes) known = known || endsWith(path, suffix);
  if (!known) {
    OsmData data;
    data.error =
        "unsupported OSM file suffix (expected .osm, .osm.pbf, .osm.gz, .osm.bz2): " + path;
    return data;
  }
  FILE* probe = std::fopen(path.c_str(), "rb");
  if (!probe) {
    OsmData data;
    data.error = "cannot open OSM file " + path + ": " + std::strerror(errno);
    return data;
  }
  std::fclose(probe);
  if (endsWith(path, ".pbf")) {
    const std::string pbf_error = checkPbfBlobHeaders(path);
    if (!pbf_error.empty()) {
      OsmData data;
      data.error = path + ": " + pbf_error;
      return data;
    }
  }
  if (endsWith(path, ".osm") || endsWith(path, ".xml")) {
    // Uncompressed XML: one streaming pass for coordinates libosmium cannot parse safely; such a
    // file goes through the in-memory reader, which refuses it and keeps what precedes it.
    UnsafeCoordinateScanner scanner;
    std::ifstream in(path, std::ios::binary);
    std::vector<char> chunk(1 << 20);
    while (in) {
      in.read(chunk.data(), static_cast<std::streamsize>(chunk.size()));
      if (!scanner.feed(chunk.data(), static_cast<size_t>(in.gcount()))) break;
    }
    if (scanner.found()) {
      OsmData data;
      data.error = unsafeCoordinateError(scanner);
      data = salvageXmlFile(path, options, std::move(data));
      data.error = path + ": " + data.error;
      return data;
    }
  } else if (endsWith(path, ".osm.gz") || endsWith(path, ".osm.bz2")) {
    // Compressed XML: the same pass over the decompressed stream (a stream that cannot be
    // decompressed is left for libosmium to report); such a file is refused as a whole.
    UnsafeCoordinateScanner scanner;
    std::vector<char> chunk(1 << 20);
    if (endsWith(path, ".gz")) {
      if (gzFile gz = gzopen(path.c_str(), "rb")) {
        int n = 0;
        while ((n = gzread(gz, chunk.data(), static_cast<unsigned>(chunk.size()))) > 0 &&
               scanner.feed(chunk.data(), static_cast<size_t>(n))) {
        }
        gzclose(gz);
      }
    } else if (FILE* file = std::fopen(path.c_str(), "rb")) {
      int bz_error = BZ_OK;
      if (BZFILE* bz = BZ2_bzReadOpen(&bz_error, file, 0, 0, nullptr, 0)) {
        while (bz_error == BZ_OK) {
          const int n = BZ2_bzRead(&bz_error, bz, chunk.data(), static_cast<int>(chunk.size()));
          if ((bz_error != BZ_OK && bz_error != BZ_STREAM_END) || n <= 0) break;
          if (!scanner.feed(chunk.data(), static_cast<size_t>(n))) break;
        }
        BZ2_bzReadClose(&bz_error, bz);
      }
      std::fclose(file);
    }
    if (scanner.found()) {
      OsmData data;
      data.error = path + ": " + unsafeCoordinateError(scanner);
      return data;
    }
  }
  const MappedFile mapped(path);
  if (!mapped.data()) {
    OsmData data;
    data.error = "cannot read OSM file " + path + ": " + mapped.error();
    return data;
  }
  XmlErrorPosition position;
  OsmData data = readWithCollector(
      [&] {
        return osmium::io::File{mapped.data(), mapped.size(), bufferFormat(path)};
      },
      options, &position);
  if (!data.ok && position.valid && !endsWith(path, ".gz") && !endsWith(path, ".bz2")) {
    data = salvageXmlFile(path, options, std::move(data));
  }
  if (!data.ok) data.error = path + ": " + data.error;
  return data;
}

namespace {

OsmData parseXmlOnce(const std::string& xml, const OsmReadOptions& options,
                     XmlErrorPosition* error_position) {
  return readWithCollector(
      [&] {
        return osmium::io::File{xml.data(), xml.size(), "osm"};
      },
      options, error_position);
}

/// Byte offset of a (1-based line, 0-based column) position reported by expat.
size_t offsetOf(const std::string& text, uint64_t line, uint64_t column) {
  size_t offset = 0;
  for (uint64_t l = 1; l < line && offset < text.size(); ++l) {
    const size_t nl = text.find('\n', offset);
    if (nl == std::string::npos) return text.size();
    offset = nl + 1;
  }
  return std::min(text.size(), offset + column);
}

/// End of the last complete top-level element (node, way, relation) in prefix, or 0.
size_t lastCompleteElementEnd(const std::string& prefix) {
  size_t end = 0;
  for (const char* tag : {"</node>", "</way>", "</relation>"}) {
    const size_t p = prefix.rfind(tag);
    if (p != std::string::npos) end = std::max(end, p + std::strlen(tag));
  }
  const size_t node = prefix.rfind("<node ");
  if (node != std::string::npos) {
    const size_t close = prefix.find("/>", node);
    const size_t next_tag = prefix.find('<', node + 1);
    if (close != std::string::npos && (next_tag == std::string::npos || close < next_tag)) {
      end = std::max(end, close + 2);
    }
  }
  return end;
}

}  // namespace

OsmData parseOsmXml(const std::string& xml, const OsmReadOptions& options) {
  if (xml.empty()) {
    OsmData data;
    data.error = "empty OSM XML document";
    return data;
  }
  UnsafeCoordinateScanner scanner;
  scanner.feed(xml.data(), xml.size());
  XmlErrorPosition position;
  OsmData data;
  size_t error_offset = 0;
  if (scanner.found()) {
    data.error = unsafeCoordinateError(scanner);
    error_offset = scanner.offset();
  } else {
    data = parseXmlOnce(xml, options, &position);
    if (data.ok || !position.valid) return data;
    error_offset = offsetOf(xml, position.line, position.column);
  }
  // libosmium drops the block it was parsing when expat fails; re-parse the part before the
  // error, closed after its last complete element, so that everything read is kept.
  const std::string prefix = xml.substr(0, error_offset);
  const size_t cut = lastCompleteElementEnd(prefix);
  const size_t root = prefix.find("<osm");
  if (cut == 0 || root == std::string::npos || cut < root) return data;
  OsmData salvaged = parseXmlOnce(prefix.substr(0, cut) + "\n</osm>\n", options, nullptr);
  if (!salvaged.ok) return data;
  salvaged.ok = false;
  salvaged.error = data.error + " (kept the " + std::to_string(salvaged.buildings.size()) +
                   " buildings and " + std::to_string(salvaged.roads.size()) +
                   " roads read before it)";
  return salvaged;
}

namespace {

/// An uncompressed XML file that failed part-way is re-read in memory so that parseOsmXml can
/// keep the complete elements before the error (bounded: only files up to 256 MiB).
OsmData salvageXmlFile(const std::string& path, const OsmReadOptions& options, OsmData data) {
  constexpr size_t kMaxSalvageBytes = 256u << 20;
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec || size > kMaxSalvageBytes) return data;
  std::ifstream in(path, std::ios::binary);
  std::string text(static_cast<size_t>(size), '\0');
  if (!in.read(text.data(), static_cast<std::streamsize>(size))) return data;
  OsmData salvaged = parseOsmXml(text, options);
  return salvaged.buildings.size() + salvaged.roads.size() >=
                 data.buildings.size() + data.roads.size()
             ? salvaged
             : data;
}

}  // namespace

}  // namespace osm_graph_slam
