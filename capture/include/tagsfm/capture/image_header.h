#pragma once
// The size an encoded PNG, JPEG or PGM/PPM claims in its header, read before
// decoding: a decoder allocates what the header claims (OpenCV up to 1 Gpx,
// 3 GB in colour), so a corrupt or hostile file of a few bytes could
// exhaust a rig's memory (found by fuzz/image_decode_fuzz.cpp).
#include <cstddef>
#include <cstdint>
#include <optional>

namespace tagsfm {

struct EncodedSize {
  long long width = 0, height = 0;
};

// Empty for another format, or a header too short or without a size.
std::optional<EncodedSize> EncodedImageSize(const std::uint8_t* data, size_t size);

// The most pixels a frame file may claim: 64 Mpx (a 12 Mpx phone photo is
// 12; the largest machine-vision sensors ~150 are not rig cameras).
constexpr long long kMaxFramePixels = 64LL << 20;

// More than kMaxFramePixels (each side checked first: a PNG's 32-bit sides
// multiplied overflow a 64-bit count).
inline bool ClaimsTooManyPixels(const EncodedSize& size) {
  return size.width > kMaxFramePixels || size.height > kMaxFramePixels || size.width * size.height > kMaxFramePixels;
}

}  // namespace tagsfm
