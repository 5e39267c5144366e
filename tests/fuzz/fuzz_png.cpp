// SPDX-License-Identifier: BSD-3-Clause
// Camera images (cleanmap::io::readImage, DESIGN §3). The first byte picks how the rest becomes a
// file: 0 the bytes themselves; 1 an 8-bit RGB PNG whose zlib stream they are; 2 one whose
// filtered rows they are, compressed here; 3 as 1 with the header's bit depth and colour type from
// the next two bytes. 1 to 3 get right chunk CRCs and a width and height from the next bytes, so
// that the fuzzer reaches the inflation and the row filters rather than the CRC check. A decoded
// image must have the header's size.
#include <cstring>

#include <libdeflate.h>
#include <opencv2/imgcodecs.hpp>

#include "cleanmap/io/image.h"
#include "fuzz_support.h"

namespace {

using Bytes = std::vector<unsigned char>;

void put32(Bytes& b, uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) b.push_back(static_cast<unsigned char>(v >> s));
}

void chunk(Bytes& b, const char* type, const Bytes& data) {
  put32(b, static_cast<uint32_t>(data.size()));
  const std::size_t at = b.size();
  b.insert(b.end(), type, type + 4);
  b.insert(b.end(), data.begin(), data.end());
  put32(b, libdeflate_crc32(0, &b[at], b.size() - at));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cleanmap;
  if (size < 1) return 0;
  const int mode = data[0] % 4;
  Bytes file;
  uint32_t w = 0, h = 0;
  if (mode == 0) {
    file.assign(data + 1, data + size);
  } else {
    const std::size_t head = mode == 3 ? 5 : 3;
    if (size < head) return 0;
    w = 1 + data[1] % 64;
    h = 1 + data[2] % 64;
    Bytes ihdr;
    put32(ihdr, w);
    put32(ihdr, h);
    const unsigned char depth = mode == 3 ? data[3] : 8, colour = mode == 3 ? data[4] : 2;
    ihdr.insert(ihdr.end(), {depth, colour, 0, 0, 0});
    Bytes body(data + head, data + size);
    if (mode == 2) {  // the rows as given, deflated
      libdeflate_compressor* c = libdeflate_alloc_compressor(1);
      Bytes z(libdeflate_zlib_compress_bound(c, body.size()));
      z.resize(libdeflate_zlib_compress(c, body.data(), body.size(), z.data(), z.size()));
      libdeflate_free_compressor(c);
      body = std::move(z);
    }
    file = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    chunk(file, "IHDR", ihdr);
    chunk(file, "IDAT", body);
    chunk(file, "IEND", {});
  }
  const std::string path = fuzz::writeInput("000000.png", file.data(), file.size());
  fuzz::expectCleanError(path, [&] {
    const cv::Mat img = io::readImage(path, cv::IMREAD_COLOR);
    if (img.empty()) fuzz::finding("an empty image returned", path);
    if (w > 0 && (img.cols != static_cast<int>(w) || img.rows != static_cast<int>(h)))
      fuzz::finding("the decoded image is not the header's size", path);
  });
  return 0;
}
