// A PNG writer for the tests and the fuzzers' seed corpus: libpng's full API, rows given as PNG
// stores them (16-bit samples big-endian), so the readers under test see real encoder output.
#pragma once

#include <png.h>

#include <csetjmp>
#include <cstdio>

namespace octovk::test {

// A PNG of `width` x `height` pixels of `bit_depth` and `color_type` from `rows`.
// Only plain data lives in this frame, so libpng's longjmp skips no destructor.
inline bool writePngRows(const char* path, png_uint_32 width, png_uint_32 height, int bit_depth,
                  int color_type, int interlace, png_bytepp rows) {
  std::FILE* file = std::fopen(path, "wb");
  if (!file) return false;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info || setjmp(png_jmpbuf(png))) {
    if (png) png_destroy_write_struct(&png, info ? &info : nullptr);
    std::fclose(file);
    return false;
  }
  png_init_io(png, file);
  png_set_IHDR(png, info, width, height, bit_depth, color_type, interlace,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return std::fclose(file) == 0;
}

}  // namespace octovk::test
