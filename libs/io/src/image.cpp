// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/image.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <memory>

#include <libdeflate.h>
#include <opencv2/imgcodecs.hpp>

#include "cleanmap/core/error.h"

namespace cleanmap::io {
namespace {

constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};

uint32_t be32(const unsigned char* p) {
  return uint32_t{p[0]} << 24 | uint32_t{p[1]} << 16 | uint32_t{p[2]} << 8 | uint32_t{p[3]};
}

// What the chunk walk found in a PNG file (the PNG specification's layout).
struct PngLayout {
  bool header = false;  // IHDR first, 13 bytes: the fields below
  uint32_t width = 0, height = 0;
  int depth = 0, colour = 0, compression = 0, filter = 0, interlace = 0;
  // Only chunks that leave OpenCV's pixels as the samples: IHDR, one run of IDAT, IEND, text,
  // time, pixel size (a palette, transparency, gamma or profile sends the file to OpenCV).
  bool plain = true;
  std::vector<std::pair<std::size_t, uint32_t>> idat;  // each IDAT's data: offset, length
};

// Deflate packs at most 1032 bytes into one (a 258-byte match in two bits). A header that claims
// more pixels than the image data can hold is refused before a decoder allocates for it (OpenCV
// allocates the image the header claims, up to 2^30 pixels, before it reads the data).
void requireRoomForPixels(const PngLayout& L, const std::string& path) {
  static constexpr int kChannels[7] = {1, 0, 3, 1, 2, 0, 4};  // by colour type; 0: not one
  if (!L.header || L.colour < 0 || L.colour > 6 || kChannels[L.colour] == 0 ||
      L.width > (1u << 20) || L.height > (1u << 20))  // OpenCV refuses these sides unallocated
    return;
  const std::size_t bits = std::size_t{L.width} * kChannels[L.colour] * std::size_t(L.depth);
  const std::size_t samples = (bits + 7) / 8 * L.height;  // every interlace pass holds as many
  std::size_t data = 0;
  for (const auto& chunk : L.idat) data += chunk.second;
  if (samples / 1032 > data + 1)
    throw Error(path, "corrupt PNG image (its " + std::to_string(data) +
                          " bytes of image data cannot hold its " + std::to_string(L.width) +
                          " x " + std::to_string(L.height) + " pixels)");
}

bool ignorable(const unsigned char* type) {
  for (const char* t : {"tEXt", "zTXt", "iTXt", "tIME", "pHYs"})
    if (std::memcmp(type, t, 4) == 0) return true;
  return false;
}

// The chunks (length, type, data, the CRC-32 of type and data) walked to IEND, each whole and its
// CRC right. libpng meets a cut (an interrupted copy) or a corrupt chunk only while it decodes,
// and prints its own "libpng error" line before OpenCV returns an empty image; it is told here in
// one line instead. Bytes after IEND are ignored, as libpng does; a file without the PNG
// signature is left to OpenCV (a JPEG named .png).
PngLayout walkPng(const std::vector<unsigned char>& b, const std::string& path) {
  PngLayout L;
  if (b.size() < 8 || !std::equal(kSignature, kSignature + 8, b.begin())) return L;
  bool idat_ended = false;
  for (std::size_t at = 8;;) {
    // 12 bytes around the data: its length and type before, its CRC after.
    if (b.size() - at < 12 || be32(&b[at]) > b.size() - at - 12)
      throw Error(path, "truncated PNG image (no IEND chunk at its end)");
    const uint32_t len = be32(&b[at]);
    const unsigned char* type = &b[at + 4];
    if (libdeflate_crc32(0, type, std::size_t{len} + 4) != be32(&b[at + 8 + len]))
      throw Error(path, "corrupt PNG image (its " + std::string(type, type + 4) +
                            " chunk at byte " + std::to_string(at) + " fails its CRC check)");
    const unsigned char* data = type + 4;
    if (at == 8) {
      L.header = std::memcmp(type, "IHDR", 4) == 0 && len == 13;
      if (L.header) {
        L.width = be32(data);
        L.height = be32(data + 4);
        L.depth = data[8];
        L.colour = data[9];
        L.compression = data[10];
        L.filter = data[11];
        L.interlace = data[12];
      }
    } else if (std::memcmp(type, "IDAT", 4) == 0) {
      L.plain = L.plain && !idat_ended;
      L.idat.emplace_back(at + 8, len);
    } else if (std::memcmp(type, "IEND", 4) == 0) {
      requireRoomForPixels(L, path);
      return L;
    } else {
      idat_ended = !L.idat.empty();
      L.plain = L.plain && ignorable(type);
    }
    at += std::size_t{len} + 12;
  }
}

// An 8-bit RGB PNG, not interlaced, as cv::IMREAD_COLOR has it: BGR.
bool decodesHere(const PngLayout& L, int flags) {
  // Up to 2^20 pixels a side (OpenCV's limit) and 2^30 bytes of samples; larger ones are
  // OpenCV's to refuse.
  return flags == cv::IMREAD_COLOR && L.header && L.plain && !L.idat.empty() && L.depth == 8 &&
         L.colour == 2 && L.compression == 0 && L.filter == 0 && L.interlace == 0 && L.width > 0 &&
         L.height > 0 && L.width <= (1u << 20) && L.height <= (1u << 20) &&
         (std::size_t{L.width} * 3 + 1) * L.height <= (std::size_t{1} << 30);
}

// One row's samples from its filtered bytes, in place (the PNG specification's filter types 0-4
// with 3 bytes a pixel); `up` is the row above, reconstructed (zeros for the first).
bool unfilter(int type, unsigned char* s, const unsigned char* up, std::size_t n) {
  constexpr std::size_t bpp = 3;
  switch (type) {
    case 0:
      return true;
    case 1: {  // Sub: the running sums of each channel, in registers
      unsigned char r = s[0], g = s[1], b = s[2];
      for (std::size_t i = bpp; i < n; i += bpp) {
        s[i] = r = static_cast<unsigned char>(s[i] + r);
        s[i + 1] = g = static_cast<unsigned char>(s[i + 1] + g);
        s[i + 2] = b = static_cast<unsigned char>(s[i + 2] + b);
      }
      return true;
    }
    case 2:  // Up
      for (std::size_t i = 0; i < n; ++i) s[i] = static_cast<unsigned char>(s[i] + up[i]);
      return true;
    case 3:  // Average
      for (std::size_t i = 0; i < n; ++i) {
        const int left = i >= bpp ? s[i - bpp] : 0;
        s[i] = static_cast<unsigned char>(s[i] + ((left + up[i]) >> 1));
      }
      return true;
    case 4:  // Paeth
      for (std::size_t i = 0; i < n; ++i) {
        const int a = i >= bpp ? s[i - bpp] : 0, b = up[i], c = i >= bpp ? up[i - bpp] : 0;
        const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
        const int pred = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
        s[i] = static_cast<unsigned char>(s[i] + pred);
      }
      return true;
    default:
      return false;
  }
}

cv::Mat decodeRgb8(const std::vector<unsigned char>& b, const PngLayout& L,
                   const std::string& path) {
  const std::size_t w = L.width, h = L.height, n = 3 * w, row = n + 1;
  // Kept by the thread (the reading thread decodes every image): no fresh pages per image.
  thread_local std::vector<unsigned char> joined, raw, zeros;
  const unsigned char* in = &b[L.idat.front().first];
  std::size_t in_n = L.idat.front().second;
  if (L.idat.size() > 1) {
    joined.clear();
    for (const auto& [at, len] : L.idat) joined.insert(joined.end(), &b[at], &b[at] + len);
    in = joined.data();
    in_n = joined.size();
  }
  raw.resize(row * h);
  const std::unique_ptr<libdeflate_decompressor, void (*)(libdeflate_decompressor*)> inflater(
      libdeflate_alloc_decompressor(), &libdeflate_free_decompressor);
  if (!inflater) throw std::bad_alloc();
  std::size_t used = 0, out = 0;
  // Bytes after the zlib stream are ignored, as libpng does; its Adler-32 is checked.
  if (libdeflate_zlib_decompress_ex(inflater.get(), in, in_n, raw.data(), raw.size(), &used,
                                    &out) != LIBDEFLATE_SUCCESS ||
      out != raw.size())
    throw Error(path, "corrupt PNG image (its image data does not inflate to " + std::to_string(h) +
                          " rows of " + std::to_string(w) + " RGB pixels)");
  zeros.assign(n, 0);
  cv::Mat img(static_cast<int>(h), static_cast<int>(w), CV_8UC3);
  const unsigned char* up = zeros.data();
  for (std::size_t y = 0; y < h; ++y) {
    unsigned char* s = &raw[y * row];
    if (!unfilter(s[0], s + 1, up, n))
      throw Error(path, "corrupt PNG image (row " + std::to_string(y) + " has filter type " +
                            std::to_string(s[0]) + ", not 0-4)");
    ++s;
    unsigned char* o = img.ptr<unsigned char>(static_cast<int>(y));
    for (std::size_t i = 0; i < n; i += 3) {  // RGB to OpenCV's BGR
      o[i] = s[i + 2];
      o[i + 1] = s[i + 1];
      o[i + 2] = s[i];
    }
    up = s;
  }
  return img;
}

std::vector<unsigned char> readBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary | std::ios::ate);
  if (!f) throw Error(path, "cannot open image");
  std::vector<unsigned char> bytes(
      static_cast<std::size_t>(std::max<std::streamoff>(f.tellg(), 0)));
  f.seekg(0);
  if (!f.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size())))
    throw Error(path, "cannot read image");
  return bytes;
}

}  // namespace

cv::Mat decodeImage(const std::vector<unsigned char>& bytes, const std::string& path, int flags) {
  const PngLayout L = walkPng(bytes, path);
  if (decodesHere(L, flags)) return decodeRgb8(bytes, L, path);
  // OpenCV asserts on an empty buffer (cv::Exception): an empty file is told as such.
  if (bytes.empty()) throw Error(path, "empty image file");
  cv::Mat img;
  try {
    img = cv::imdecode(bytes, flags);
  } catch (const cv::Exception&) {  // a decoder's failed check: no image
  }
  if (img.empty()) throw Error(path, "cannot decode image");
  return img;
}

bool decodedHere(const std::vector<unsigned char>& bytes, const std::string& path, int flags) {
  return decodesHere(walkPng(bytes, path), flags);
}

cv::Mat readImage(const std::string& path, int flags) {
  return decodeImage(readBytes(path), path, flags);
}

std::pair<int, int> imageSize(const std::string& path) {
  const auto bytes = readBytes(path);
  const PngLayout L = walkPng(bytes, path);
  if (decodesHere(L, cv::IMREAD_COLOR))
    return {static_cast<int>(L.width), static_cast<int>(L.height)};
  const cv::Mat img = decodeImage(bytes, path, cv::IMREAD_UNCHANGED);
  return {img.cols, img.rows};
}

}  // namespace cleanmap::io
