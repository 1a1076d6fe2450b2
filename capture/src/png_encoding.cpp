#include "tagsfm/capture/png_encoding.h"

#include <png.h>
#include <zlib.h>

#include <string>

namespace tagsfm {
namespace {

struct Output {
  std::vector<unsigned char> bytes;
  std::string error;
};

void Append(png_structp png, png_bytep data, png_size_t size) {
  auto* out = static_cast<Output*>(png_get_io_ptr(png));
  try {
    out->bytes.insert(out->bytes.end(), data, data + size);
  } catch (const std::exception&) {
    png_error(png, "out of memory");  // no C++ exception may cross libpng's C frames
  }
}

void Flush(png_structp) {}

void OnError(png_structp png, png_const_charp message) {
  auto* out = static_cast<Output*>(png_get_error_ptr(png));
  out->error = message;
  png_longjmp(png, 1);
}

void OnWarning(png_structp, png_const_charp) {}

// The image's rows through libpng; false with out->error set when it fails.
// Nothing here lives past setjmp but the arguments, so longjmp clobbers
// nothing.
bool WriteRows(png_structp png, png_infop info, const cv::Mat& image, int colour_type, Output* out) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_write_fn(png, out, Append, Flush);
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.cols), static_cast<png_uint_32>(image.rows),
               image.depth() == CV_16U ? 16 : 8, colour_type, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_BASE,
               PNG_FILTER_TYPE_BASE);
  // Up costs one subtraction a byte to undo (Paeth, libpng's usual choice,
  // a branchy predictor per byte), and its residuals of a camera image
  // compress as well under zlib's run-length strategy as the adaptive
  // filters' under the default one.
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_UP);
  png_set_compression_level(png, 1);
  png_set_compression_strategy(png, Z_RLE);
  png_write_info(png, info);
  if (image.channels() >= 3) png_set_bgr(png);      // OpenCV's order
  if (image.depth() == CV_16U) png_set_swap(png);   // PNG's 16-bit samples are big-endian
  for (int r = 0; r < image.rows; ++r) png_write_row(png, const_cast<png_bytep>(image.ptr<png_byte>(r)));
  png_write_end(png, nullptr);
  return true;
}

}  // namespace

Result<std::vector<unsigned char>> EncodePng(const cv::Mat& image) {
  if (image.empty()) return MakeError("PNG: empty image");
  if (image.depth() != CV_8U && image.depth() != CV_16U) return MakeError("PNG: only 8- and 16-bit images");
  int colour_type = 0;
  switch (image.channels()) {
    case 1: colour_type = PNG_COLOR_TYPE_GRAY; break;
    case 3: colour_type = PNG_COLOR_TYPE_RGB; break;
    case 4: colour_type = PNG_COLOR_TYPE_RGB_ALPHA; break;
    default: return MakeError("PNG: " + std::to_string(image.channels()) + " channels (1, 3 or 4 written)");
  }
  Output out;
  out.bytes.reserve(image.total() * image.elemSize() / 2);
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &out, OnError, OnWarning);
  if (png == nullptr) return MakeError("PNG: libpng could not start");
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    return MakeError("PNG: libpng could not start");
  }
  const bool written = WriteRows(png, info, image, colour_type, &out);
  png_destroy_write_struct(&png, &info);
  if (!written) return MakeError("PNG: " + (out.error.empty() ? std::string("libpng failed") : out.error));
  return std::move(out.bytes);
}

}  // namespace tagsfm
