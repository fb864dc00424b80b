// A PNG writer for the tests and the fuzzers' seed corpus: libpng's full API, rows given as PNG
// stores them (16-bit samples big-endian), so the readers under test see real encoder output.
#pragma once

#include <png.h>
#include <zlib.h>

#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <string>

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

// `png` with a chunk of `type` appended whose length field says `length` (the bytes that follow
// are `data`, and its checksum theirs).
inline void appendPngChunk(std::string& png, const std::string& type, const std::string& data,
                           std::uint32_t length) {
  for (int i = 0; i < 4; ++i) png += static_cast<char>(length >> (24 - 8 * i));
  const std::string body = type + data;
  png += body;
  const uLong crc =
      ::crc32(0L, reinterpret_cast<const Bytef*>(body.data()), static_cast<uInt>(body.size()));
  for (int i = 0; i < 4; ++i) png += static_cast<char>(crc >> (24 - 8 * i));
}

// Issue 22's PNG, 2,475 bytes: the signature, the header of a 4 x 3 16-bit grayscale image, then a
// tEXt chunk whose length field says 0x7fffffff (2 GiB) and which holds the rest of the file.
// libpng used to allocate the declared length before finding the file short: 2.1 GB of RSS and
// 7-9 s. The fuzz corpus holds it (tests/fuzz/corpus/depth_png/text_chunk_2gib.png, written by
// make_corpus.cpp from here) and tum_test.cpp checks the readers refuse it cheaply.
inline std::string hugeTextChunkPng() {
  std::string png("\x89PNG\r\n\x1a\n", 8);
  const std::string ihdr("\0\0\0\4\0\0\0\3\x10\0\0\0\0", 13);  // 4 x 3, 16-bit, gray, no interlace
  appendPngChunk(png, "IHDR", ihdr, 13);
  appendPngChunk(png, "tEXt", std::string("Comment\0", 8) + std::string(2422, 'x'), 0x7fffffff);
  return png;
}

}  // namespace octovk::test
