#pragma once
// Reading YAML files (recording.yaml, capture settings, scene.yaml) with
// errors that name the file and the field, the same way everywhere.
#include <optional>
#include <string>

#include <yaml-cpp/yaml.h>

#include "tagsfm/core/result.h"

namespace tagsfm {

// The file's top-level node. Errors: "FILE: cannot open", "FILE: not valid
// YAML (line N)", and, unless `allow_empty`, "FILE: expected a mapping at
// the top level" for anything but a mapping (an empty file included).
Result<YAML::Node> LoadYamlFile(const std::string& file, bool allow_empty = false);

// A mapping key as text for messages and lookups: a plain key as written, a
// complex one ("? [a, b]" or "? {a: 1}") as YAML, where as<std::string>()
// would throw (found by fuzzing the run config).
inline std::string YamlKeyText(const YAML::Node& key) { return key.IsScalar() ? key.Scalar() : YAML::Dump(key); }

// Reads node[key] as T into *out. A missing key is an error only when
// `required` ("WHEREkey is missing"); a value of the wrong type always is
// ("WHEREkey has the wrong type: 'VALUE'"). `where` is the prefix that names
// the file and the block, e.g. "rec/recording.yaml: camera.".
template <class T>
Status ReadYamlField(const YAML::Node& node, const std::string& key, const std::string& where, T* out,
                     bool required = false) {
  std::optional<YAML::Node> found;
  try {
    found.emplace(node[key]);  // throws when `node` is a scalar, not a block of fields
  } catch (const YAML::Exception&) {
    return MakeError(where + key + ": the block is not a mapping of fields: '" + YAML::Dump(node) + "'");
  }
  const YAML::Node& value = *found;
  if (!value) {
    if (required) return MakeError(where + key + " is missing");
    return Status::Ok();
  }
  try {
    *out = value.as<T>();
  } catch (const YAML::Exception&) {
    return MakeError(where + key + " has the wrong type: '" + YAML::Dump(value) + "'");
  }
  return Status::Ok();
}

}  // namespace tagsfm
