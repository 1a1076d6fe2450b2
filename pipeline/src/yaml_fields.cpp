#include "yaml_fields.h"

#include <cmath>
#include <type_traits>

#include "tagsfm/capture/yaml_file.h"

namespace tagsfm {
namespace {

template <class T>
const char* Expected() {
  if constexpr (std::is_same_v<T, bool>) return "true or false";
  if constexpr (std::is_integral_v<T>) return "a whole number";
  if constexpr (std::is_floating_point_v<T>) return "a number";
  return "text";
}

// A field yaml-cpp did not find is an invalid node, and asking its type throws.
bool IsMap(const YAML::Node& node) { return node.IsDefined() && node.IsMap(); }

}  // namespace

YamlFields::YamlFields(YAML::Node node, std::string place, std::filesystem::path file, Status* status)
    : node_(std::move(node)), place_(std::move(place)), file_(std::move(file)), status_(status) {
  if (node_.IsDefined() && !node_.IsNull() && !node_.IsMap()) Fail("", "expected a block of fields");
}

void YamlFields::Fail(const std::string& name, const std::string& why) {
  if (!*status_) return;  // the first error is the one reported
  const std::string field = name.empty() ? place_ : place_ + "." + name;
  *status_ = MakeError(file_.string() + ": " + field + ": " + why);
}

template <class T>
bool YamlFields::Take(const char* name, T* value) {
  known_.insert(name);
  const YAML::Node& node = node_;  // const: looking a field up must not add it
  if (!*status_ || !IsMap(node) || !node[name].IsDefined()) return false;
  try {
    const T read = node[name].as<T>();
    if constexpr (std::is_floating_point_v<T>) {
      if (!std::isfinite(read)) throw YAML::Exception(YAML::Mark(), "not finite");
    }
    *value = read;
    return true;
  } catch (const YAML::Exception&) {
    Fail(name, std::string("expected ") + Expected<T>());
    return false;
  }
}

bool YamlFields::Read(const char* name, double* value) { return Take(name, value); }
bool YamlFields::Read(const char* name, float* value) { return Take(name, value); }
bool YamlFields::Read(const char* name, int* value) { return Take(name, value); }
bool YamlFields::Read(const char* name, bool* value) { return Take(name, value); }
bool YamlFields::Read(const char* name, std::string* value) { return Take(name, value); }

YamlFields YamlFields::Block(const char* name) {
  known_.insert(name);
  const YAML::Node& node = node_;
  YAML::Node child = IsMap(node) && node[name].IsDefined() ? node[name] : YAML::Node();
  return YamlFields(child, place_ + "." + name, file_, status_);
}

void YamlFields::Done() {
  if (!*status_ || !IsMap(node_)) return;
  for (const auto& item : node_) {
    const std::string key = YamlKeyText(item.first);
    if (!known_.count(key)) return Fail(key, "unknown field");
  }
}

}  // namespace tagsfm
