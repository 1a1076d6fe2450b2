#pragma once
// Reading an options struct from a YAML map field by field: each error names
// the file and the field's place in the block ("FILE: pipeline.recon.ba.huber_px:
// expected a number"), and a field the reader does not know is an error too
// (a typo would otherwise be ignored silently).
#include <filesystem>
#include <functional>
#include <set>
#include <string>

#include <yaml-cpp/yaml.h>

#include "tagsfm/core/result.h"

namespace tagsfm {

class YamlFields {
 public:
  // `status` collects the first error of this reader and its blocks.
  YamlFields(YAML::Node node, std::string place, std::filesystem::path file, Status* status);

  bool Read(const char* name, double* value);
  bool Read(const char* name, float* value);
  bool Read(const char* name, int* value);
  bool Read(const char* name, bool* value);
  bool Read(const char* name, std::string* value);
  // Each Read says whether the field was there and read.
  // A named choice: `parse` turns the text into the value or says why not.
  template <class T>
  void ReadChoice(const char* name, T* value, const std::function<Result<T>(const std::string&)>& parse) {
    std::string text;
    if (!Read(name, &text)) return;
    auto parsed = parse(text);
    if (!parsed) return Fail(name, parsed.error().message);
    *value = *parsed;
  }
  // A nested block (absent: an empty one).
  YamlFields Block(const char* name);
  // Unknown fields of this block are an error.
  void Done();

 private:
  template <class T>
  bool Take(const char* name, T* value);
  void Fail(const std::string& name, const std::string& why);

  YAML::Node node_;
  std::string place_;
  std::filesystem::path file_;
  Status* status_;
  std::set<std::string> known_;
};

}  // namespace tagsfm
