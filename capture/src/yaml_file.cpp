#include "tagsfm/capture/yaml_file.h"

namespace tagsfm {

Result<YAML::Node> LoadYamlFile(const std::string& file, bool allow_empty) {
  try {
    YAML::Node root = YAML::LoadFile(file);
    if (root.IsMap() || (allow_empty && root.IsNull())) return root;
    return MakeError(file + ": expected a mapping at the top level");
  } catch (const YAML::BadFile&) {
    return MakeError(file + ": cannot open");
  } catch (const YAML::Exception& e) {
    return MakeError(file + ": not valid YAML (line " + std::to_string(e.mark.line + 1) + ")");
  }
}

}  // namespace tagsfm
