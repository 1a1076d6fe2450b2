#include "tagsfm/eval/ply_reader.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <sstream>
#include <string_view>

#include "tagsfm/core/file_util.h"

namespace tagsfm::eval {
namespace {

enum class Encoding { kAscii, kLittleEndian, kBigEndian };

struct Property {
  std::string name;
  std::string type;        // scalar type, or the item type of a list
  std::string count_type;  // non-empty for a list property
};

struct Element {
  std::string name;
  long long count = 0;
  std::vector<Property> properties;
};

int TypeSize(const std::string& type) {
  if (type == "char" || type == "uchar" || type == "int8" || type == "uint8") return 1;
  if (type == "short" || type == "ushort" || type == "int16" || type == "uint16") return 2;
  if (type == "int" || type == "uint" || type == "int32" || type == "uint32") return 4;
  if (type == "float" || type == "float32") return 4;
  if (type == "double" || type == "float64") return 8;
  return 0;
}

// Reads the values of the body one at a time, in either encoding.
class BodyReader {
 public:
  BodyReader(std::string_view body, Encoding encoding) : body_(body), encoding_(encoding) {}

  bool Read(const std::string& type, double* value) {
    if (encoding_ == Encoding::kAscii) return ReadToken(value);
    const size_t size = static_cast<size_t>(TypeSize(type));
    if (pos_ + size > body_.size()) return false;
    unsigned char bytes[8];
    std::memcpy(bytes, body_.data() + pos_, size);
    pos_ += size;
    const bool file_is_little = encoding_ == Encoding::kLittleEndian;
    if (file_is_little != (std::endian::native == std::endian::little)) std::reverse(bytes, bytes + size);
    *value = Decode(type, bytes);
    return true;
  }

 private:
  static double Decode(const std::string& type, const unsigned char* b) {
    auto as = [b](auto v) {
      std::memcpy(&v, b, sizeof v);
      return static_cast<double>(v);
    };
    if (type == "char" || type == "int8") return as(std::int8_t{});
    if (type == "uchar" || type == "uint8") return as(std::uint8_t{});
    if (type == "short" || type == "int16") return as(std::int16_t{});
    if (type == "ushort" || type == "uint16") return as(std::uint16_t{});
    if (type == "int" || type == "int32") return as(std::int32_t{});
    if (type == "uint" || type == "uint32") return as(std::uint32_t{});
    if (type == "float" || type == "float32") return as(float{});
    return as(double{});
  }

  bool ReadToken(double* value) {
    while (pos_ < body_.size() && std::isspace(static_cast<unsigned char>(body_[pos_]))) ++pos_;
    const size_t start = pos_;
    while (pos_ < body_.size() && !std::isspace(static_cast<unsigned char>(body_[pos_]))) ++pos_;
    return start < pos_ && ParseDouble(body_.substr(start, pos_ - start), value);
  }

  std::string_view body_;
  Encoding encoding_;
  size_t pos_ = 0;
};

struct Header {
  Encoding encoding = Encoding::kAscii;
  std::vector<Element> elements;
  size_t body_offset = 0;
};

Result<Header> ParseHeader(const std::string& text, const std::string& file) {
  Header header;
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line) || line.substr(0, 3) != "ply") return MakeError(file + ": not a PLY file (no 'ply' line)");
  bool have_format = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (keyword == "end_header") {
      // At the end of the file (no newline after end_header) tellg fails: no body.
      const auto offset = in.tellg();
      header.body_offset = offset < 0 ? text.size() : static_cast<size_t>(offset);
      if (!have_format) return MakeError(file + ": header has no format line");
      return header;
    }
    if (keyword == "format") {
      std::string format;
      words >> format;
      if (format == "ascii") header.encoding = Encoding::kAscii;
      else if (format == "binary_little_endian") header.encoding = Encoding::kLittleEndian;
      else if (format == "binary_big_endian") header.encoding = Encoding::kBigEndian;
      else return MakeError(file + ": unknown format '" + format + "'");
      have_format = true;
    } else if (keyword == "element") {
      Element element;
      if (!(words >> element.name >> element.count) || element.count < 0) {
        return MakeError(file + ": malformed element line '" + line + "'");
      }
      header.elements.push_back(element);
    } else if (keyword == "property") {
      if (header.elements.empty()) return MakeError(file + ": property before any element");
      Property p;
      words >> p.type;
      if (p.type == "list") {
        p.count_type = "";
        words >> p.count_type >> p.type;
        if (TypeSize(p.count_type) == 0) return MakeError(file + ": unknown list count type in '" + line + "'");
      }
      words >> p.name;
      if (TypeSize(p.type) == 0 || p.name.empty()) return MakeError(file + ": malformed property line '" + line + "'");
      header.elements.back().properties.push_back(p);
    } else if (keyword != "comment" && keyword != "obj_info" && !keyword.empty()) {
      return MakeError(file + ": unknown header line '" + line + "'");
    }
  }
  return MakeError(file + ": header has no end_header");
}

}  // namespace

Result<std::vector<Eigen::Vector3d>> ReadPlyPoints(const std::filesystem::path& path) {
  const std::string file = path.string();
  Result<std::string> text = ReadFileToString(path);
  if (!text) return text.error();
  Result<Header> header = ParseHeader(*text, file);
  if (!header) return header.error();
  BodyReader body(std::string_view(*text).substr(header->body_offset), header->encoding);
  for (const Element& element : header->elements) {
    const bool is_vertex = element.name == "vertex";
    int xyz_index[3] = {-1, -1, -1};
    for (size_t p = 0; p < element.properties.size(); ++p) {
      const std::string& name = element.properties[p].name;
      if (name.size() == 1 && name[0] >= 'x' && name[0] <= 'z' && element.properties[p].count_type.empty()) {
        xyz_index[name[0] - 'x'] = static_cast<int>(p);
      }
    }
    if (is_vertex && (xyz_index[0] < 0 || xyz_index[1] < 0 || xyz_index[2] < 0)) {
      return MakeError(file + ": the vertex element lacks a scalar x, y or z property");
    }
    // An element without properties has nothing in the body, however many
    // it claims: its count is not looped over (10^15 of them hung the reader).
    if (!is_vertex && element.properties.empty()) continue;
    std::vector<Eigen::Vector3d> points;
    // The header's count is not trusted for the allocation: a point takes at least a byte.
    if (is_vertex) points.reserve(static_cast<size_t>(std::min<long long>(element.count, static_cast<long long>(text->size()))));
    for (long long i = 0; i < element.count; ++i) {
      Eigen::Vector3d point;
      for (size_t p = 0; p < element.properties.size(); ++p) {
        const Property& property = element.properties[p];
        double value = 0;
        const bool ok = property.count_type.empty() ? body.Read(property.type, &value) : [&] {
          double items = 0;
          // A list count read as float may be NaN or beyond long long; the items run out long before 2^31.
          if (!body.Read(property.count_type, &items) || !(items >= 0 && items <= 2147483647.0)) return false;
          for (long long k = 0; k < static_cast<long long>(items); ++k) {
            if (!body.Read(property.type, &value)) return false;
          }
          return true;
        }();
        if (!ok) {
          return MakeError(file + ": truncated or malformed at " + element.name + " " + std::to_string(i) + " of " +
                           std::to_string(element.count) + " (property " + property.name + ")");
        }
        for (int axis = 0; axis < 3; ++axis) {
          if (xyz_index[axis] == static_cast<int>(p)) point[axis] = value;
        }
      }
      if (is_vertex) {
        if (!point.allFinite()) return MakeError(file + ": vertex " + std::to_string(i) + " is not finite");
        points.push_back(point);
      }
    }
    if (is_vertex) return points;
  }
  return MakeError(file + ": no vertex element");
}

}  // namespace tagsfm::eval
