#pragma once
// The parsers under test read files by path, as tagsfm does; each fuzz input
// is written to a file of its own in a per-process folder under /dev/shm
// (memory, so the disk is not worn by millions of writes).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

namespace tagsfm::fuzz {

inline std::filesystem::path FuzzDir() {
  static const std::filesystem::path dir = [] {
    const std::filesystem::path base = std::filesystem::exists("/dev/shm") ? "/dev/shm" : std::filesystem::temp_directory_path();
    std::filesystem::path d = base / ("tagsfm_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

inline std::filesystem::path WriteInput(const std::string& name, const uint8_t* data, size_t size) {
  const std::filesystem::path path = FuzzDir() / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

inline std::filesystem::path WriteText(const std::string& name, const std::string& text) {
  return WriteInput(name, reinterpret_cast<const uint8_t*>(text.data()), text.size());
}

}  // namespace tagsfm::fuzz
