#include "tagsfm/capture/image_header.h"

namespace tagsfm {
namespace {

long long BigEndian(const std::uint8_t* p, int bytes) {
  long long v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | p[i];
  return v;
}

// PNG: the 8-byte signature, then the IHDR chunk (length, "IHDR", width, height).
std::optional<EncodedSize> PngSize(const std::uint8_t* data, size_t size) {
  static const std::uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (size < 24) return std::nullopt;
  for (int i = 0; i < 8; ++i) {
    if (data[i] != kSignature[i]) return std::nullopt;
  }
  if (data[12] != 'I' || data[13] != 'H' || data[14] != 'D' || data[15] != 'R') return std::nullopt;
  return EncodedSize{BigEndian(data + 16, 4), BigEndian(data + 20, 4)};
}

// JPEG: the markers after SOI up to the first start of frame (SOF0-SOF15
// but DHT C4, JPG C8 and DAC CC), which holds the size, walked as libjpeg
// walks them: a segment is skipped by its length (none when the length is
// below 2), and bytes up to the next FF are discarded. A stricter walk would
// stop at a broken segment that libjpeg reads past, and miss the size.
std::optional<EncodedSize> JpegSize(const std::uint8_t* data, size_t size) {
  // FF D8 FF, as OpenCV's JPEG decoder checks: a buffer it does not take
  // as a JPEG goes to the next decoder whose signature matches (GDCM's
  // DICOM reader aborted on one the fuzzer made).
  if (size < 4 || data[0] != 0xFF || data[1] != 0xD8 || data[2] != 0xFF) return std::nullopt;
  size_t at = 2;
  for (;;) {
    // The next marker: an FF (after any other bytes), its fill bytes, a code; FF 00 is none.
    for (;;) {
      while (at < size && data[at] != 0xFF) ++at;
      while (at < size && data[at] == 0xFF) ++at;
      if (at >= size) return std::nullopt;
      if (data[at] != 0x00) break;
      ++at;
    }
    const std::uint8_t marker = data[at++];
    const bool start_of_frame = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (start_of_frame) {
      // length (2), precision (1), height (2), width (2)
      if (at + 7 > size) return std::nullopt;
      return EncodedSize{BigEndian(data + at + 5, 2), BigEndian(data + at + 3, 2)};
    }
    if (marker == 0xD8 || marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) continue;  // no length
    if (marker == 0xD9 || marker == 0xDA) return std::nullopt;  // end, or scan data before any frame header
    if (at + 2 > size) return std::nullopt;
    const size_t length = static_cast<size_t>(BigEndian(data + at, 2));
    at += 2 + (length > 2 ? length - 2 : 0);
  }
}

// PGM/PPM (P2, P3, P5, P6): the magic, then width and height as decimal
// text, separated by white space and # comments, read as OpenCV's PxM
// decoder reads them, since it is the one that allocates: the byte that
// ends a number is consumed whatever it is, so in "599999#1269\n" the '#'
// opens no comment and the height is 1269; a comment ends at '\n' or '\r'.
std::optional<EncodedSize> PnmSize(const std::uint8_t* data, size_t size) {
  // The magic and a white space, as OpenCV's PxM decoder checks.
  if (size < 3 || data[0] != 'P' || !(data[1] == '2' || data[1] == '3' || data[1] == '5' || data[1] == '6') ||
      !(data[2] == ' ' || data[2] == '\t' || data[2] == '\r' || data[2] == '\n')) {
    return std::nullopt;
  }
  long long values[2] = {0, 0};
  size_t at = 2;
  for (long long& value : values) {
    for (;;) {  // white space and comments
      if (at >= size) return std::nullopt;
      if (data[at] == '#') {
        while (at < size && data[at] != '\n' && data[at] != '\r') ++at;
      } else if (data[at] == ' ' || data[at] == '\t' || data[at] == '\r' || data[at] == '\n') {
        ++at;
      } else {
        break;
      }
    }
    int digits = 0;
    for (; at < size && data[at] >= '0' && data[at] <= '9' && digits < 12; ++at, ++digits) value = 10 * value + (data[at] - '0');
    if (digits == 0) return std::nullopt;
    ++at;  // the number's terminator
  }
  return EncodedSize{values[0], values[1]};
}

}  // namespace

std::optional<EncodedSize> EncodedImageSize(const std::uint8_t* data, size_t size) {
  if (auto png = PngSize(data, size)) return png;
  if (auto jpeg = JpegSize(data, size)) return jpeg;
  return PnmSize(data, size);
}

}  // namespace tagsfm
