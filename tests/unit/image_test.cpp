// SPDX-License-Identifier: BSD-3-Clause
// io::decodeImage (DESIGN §3's camera images): its own decoder of 8-bit RGB PNGs gives OpenCV's
// pixels for every row filter, tells a corrupt file in one line, and leaves every other image to
// OpenCV.
#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <functional>
#include <random>

#include <libdeflate.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cleanmap/core/error.h"
#include "cleanmap/io/image.h"
#include "test_data.h"

using namespace cleanmap;
namespace fs = std::filesystem;

namespace {

using Bytes = std::vector<unsigned char>;

void put32(Bytes& b, uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) b.push_back(static_cast<unsigned char>(v >> s));
}

struct Chunk {
  std::string type;
  Bytes data;
};

// A PNG file of these chunks, each with its length and CRC-32.
Bytes pngOf(const std::vector<Chunk>& chunks) {
  Bytes b = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  for (const auto& c : chunks) {
    put32(b, static_cast<uint32_t>(c.data.size()));
    const std::size_t at = b.size();
    b.insert(b.end(), c.type.begin(), c.type.end());
    b.insert(b.end(), c.data.begin(), c.data.end());
    put32(b, libdeflate_crc32(0, &b[at], b.size() - at));
  }
  return b;
}

Chunk header(int w, int h) {
  Chunk c{"IHDR", {}};
  put32(c.data, static_cast<uint32_t>(w));
  put32(c.data, static_cast<uint32_t>(h));
  c.data.insert(c.data.end(), {8, 2, 0, 0, 0});  // 8 bits, RGB, deflate, adaptive, no interlace
  return c;
}

int paeth(int a, int b, int c) {
  const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}

// The image's rows (BGR in, RGB samples out) each filtered with filter(y), as an encoder does.
Bytes filteredRows(const cv::Mat& bgr, const std::function<int(int)>& filter) {
  const int n = 3 * bgr.cols;
  Bytes out, prev(static_cast<std::size_t>(n), 0), cur(static_cast<std::size_t>(n));
  for (int y = 0; y < bgr.rows; ++y) {
    const auto* p = bgr.ptr<unsigned char>(y);
    for (int i = 0; i < n; i += 3) {
      cur[i] = p[i + 2];
      cur[i + 1] = p[i + 1];
      cur[i + 2] = p[i];
    }
    const int f = filter(y);
    out.push_back(static_cast<unsigned char>(f));
    for (int i = 0; i < n; ++i) {
      const int a = i >= 3 ? cur[i - 3] : 0, b = prev[i], c = i >= 3 ? prev[i - 3] : 0;
      const int pred = f == 1 ? a : f == 2 ? b : f == 3 ? (a + b) / 2 : f == 4 ? paeth(a, b, c) : 0;
      out.push_back(static_cast<unsigned char>(cur[i] - pred));
    }
    std::swap(prev, cur);
  }
  return out;
}

Bytes zlibOf(const Bytes& raw) {
  libdeflate_compressor* c = libdeflate_alloc_compressor(6);
  Bytes z(libdeflate_zlib_compress_bound(c, raw.size()));
  z.resize(libdeflate_zlib_compress(c, raw.data(), raw.size(), z.data(), z.size()));
  libdeflate_free_compressor(c);
  return z;
}

// IHDR, `before`, the zlib data in IDAT chunks of `piece` bytes, `after`, IEND.
Bytes rgbPng(int w, int h, const Bytes& zdata, std::size_t piece,
             const std::vector<Chunk>& before = {}, const std::vector<Chunk>& after = {}) {
  std::vector<Chunk> chunks{header(w, h)};
  chunks.insert(chunks.end(), before.begin(), before.end());
  for (std::size_t at = 0; at < zdata.size(); at += piece)
    chunks.push_back({"IDAT", Bytes(zdata.begin() + static_cast<std::ptrdiff_t>(at),
                                    zdata.begin() + static_cast<std::ptrdiff_t>(
                                                        std::min(zdata.size(), at + piece)))});
  chunks.insert(chunks.end(), after.begin(), after.end());
  chunks.push_back({"IEND", {}});
  return pngOf(chunks);
}

cv::Mat noise(int w, int h, unsigned seed) {
  cv::Mat img(h, w, CV_8UC3);
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  return img;
}

void expectSame(const cv::Mat& a, const cv::Mat& b) {
  ASSERT_EQ(a.size(), b.size());
  ASSERT_EQ(a.type(), b.type());
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
}

Bytes fileBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return Bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

}  // namespace

TEST(Image, OwnPngDecoderGivesOpenCvsPixelsForEveryRowFilter) {
  const std::vector<std::function<int(int)>> patterns = {
      [](int y) { return y % 5; }, [](int y) { return (3 * y + 1) % 5; }, [](int) { return 1; },
      [](int) { return 3; }, [](int) { return 4; }};
  const std::vector<Chunk> text = {{"tEXt", {'k', 0, 'v'}}}, time = {{"tIME", Bytes(7, 1)}};
  unsigned seed = 1;
  for (const auto& [w, h] :
       std::vector<std::pair<int, int>>{{1, 1}, {5, 1}, {1, 6}, {7, 13}, {64, 48}})
    for (const auto& filter : patterns)
      for (const std::size_t piece : {std::size_t{1} << 20, std::size_t{97}}) {
        const cv::Mat img = noise(w, h, seed++);
        const Bytes png = rgbPng(w, h, zlibOf(filteredRows(img, filter)), piece, text, time);
        SCOPED_TRACE(std::to_string(w) + " x " + std::to_string(h) + ", IDAT of " +
                     std::to_string(piece));
        ASSERT_TRUE(io::decodedHere(png, "t.png", cv::IMREAD_COLOR));
        const cv::Mat own = io::decodeImage(png, "t.png", cv::IMREAD_COLOR);
        expectSame(own, cv::imdecode(png, cv::IMREAD_COLOR));
        expectSame(own, img);
      }
  // OpenCV's own encoder (its filters chosen by libpng) reads back the same way.
  Bytes written;
  const cv::Mat img = noise(33, 21, 99);
  ASSERT_TRUE(cv::imencode(".png", img, written));
  ASSERT_TRUE(io::decodedHere(written, "w.png", cv::IMREAD_COLOR));
  expectSame(io::decodeImage(written, "w.png", cv::IMREAD_COLOR), img);
}

TEST(Image, KittiImagesDecodeAsOpenCvDecodesThem) {
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  for (const char* stem : {"000000", "000029"}) {
    const std::string path = test::dataDir() + "/kitti_highway/image_2/" + stem + ".png";
    const Bytes png = fileBytes(path);
    ASSERT_TRUE(io::decodedHere(png, path, cv::IMREAD_COLOR)) << path;
    expectSame(io::readImage(path, cv::IMREAD_COLOR), cv::imdecode(png, cv::IMREAD_COLOR));
    EXPECT_EQ(io::imageSize(path), std::make_pair(1242, 375));
  }
}

TEST(Image, CorruptImageDataIsOneLineError) {
  // Chunks whole and their CRCs right, the data inside wrong (a faulty encoder): one line naming
  // the file and the fault, nothing from a codec before it.
  const cv::Mat img = noise(6, 4, 7);
  testing::internal::CaptureStderr();
  test::expectError(
      [&] {
        io::decodeImage(
            rgbPng(6, 4, zlibOf(filteredRows(img, [](int y) { return y == 2 ? 5 : 0; })), 1 << 20),
            "bad.png", cv::IMREAD_COLOR);
      },
      "bad.png", "corrupt PNG image (row 2 has filter type 5, not 0-4)");
  Bytes short_rows = filteredRows(img, [](int) { return 0; });
  short_rows.resize(short_rows.size() - 19);  // the last row missing
  test::expectError(
      [&] {
        io::decodeImage(rgbPng(6, 4, zlibOf(short_rows), 1 << 20), "short.png", cv::IMREAD_COLOR);
      },
      "short.png", "corrupt PNG image (its image data does not inflate to 4 rows of 6 RGB pixels)");
  Bytes garbage(40);
  std::mt19937 rng(3);
  for (auto& c : garbage) c = static_cast<unsigned char>(rng());
  test::expectError(
      [&] { io::decodeImage(rgbPng(6, 4, garbage, 1 << 20), "junk.png", cv::IMREAD_COLOR); },
      "junk.png", "corrupt PNG image (its image data does not inflate to");
  // A header that claims more pixels than its data can hold, RGB or not: refused before a
  // decoder allocates them (OpenCV would allocate 4 GiB for the second).
  test::expectError(
      [&] {
        io::decodeImage(rgbPng(4000, 4000, zlibOf(short_rows), 1 << 20), "big.png",
                        cv::IMREAD_COLOR);
      },
      "big.png", "corrupt PNG image (its ");
  Chunk deep = header(1 << 15, 1 << 15);
  deep.data[8] = 16;  // bits
  deep.data[9] = 6;   // RGBA
  const Bytes rows = zlibOf(Bytes(100, 0));
  test::expectError(
      [&] {
        io::decodeImage(pngOf({deep, {"IDAT", rows}, {"IEND", {}}}), "huge.png",
                        cv::IMREAD_UNCHANGED);
      },
      "huge.png", "bytes of image data cannot hold its 32768 x 32768 pixels)");
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
}

TEST(Image, OtherImagesAreDecodedByOpenCv) {
  // Grey, RGBA, 16 bits, a gamma chunk, another read mode: OpenCV's decoder, its pixels.
  const cv::Mat bgr = noise(9, 5, 11);
  cv::Mat grey, bgra, deep;
  cv::extractChannel(bgr, grey, 1);
  cv::Mat alpha(bgr.size(), CV_8UC1, cv::Scalar(200));
  cv::merge(std::vector<cv::Mat>{bgr, alpha}, bgra);
  bgr.convertTo(deep, CV_16UC3, 257);
  for (const auto& [what, img] : std::vector<std::pair<std::string, cv::Mat>>{
           {"grey", grey}, {"rgba", bgra}, {"16-bit", deep}})
    for (const int flags : {cv::IMREAD_COLOR, cv::IMREAD_UNCHANGED}) {
      SCOPED_TRACE(what + (flags == cv::IMREAD_COLOR ? ", colour" : ", unchanged"));
      Bytes png;
      ASSERT_TRUE(cv::imencode(".png", img, png));
      EXPECT_FALSE(io::decodedHere(png, "o.png", flags));
      expectSame(io::decodeImage(png, "o.png", flags), cv::imdecode(png, flags));
    }
  const Bytes rows = zlibOf(filteredRows(bgr, [](int y) { return y % 5; }));
  const Bytes gamma = rgbPng(9, 5, rows, 1 << 20, {{"gAMA", {0, 0, 0xB1, 0x8F}}});
  EXPECT_FALSE(io::decodedHere(gamma, "g.png", cv::IMREAD_COLOR));
  expectSame(io::decodeImage(gamma, "g.png", cv::IMREAD_COLOR),
             cv::imdecode(gamma, cv::IMREAD_COLOR));
  const Bytes plain = rgbPng(9, 5, rows, 1 << 20);
  EXPECT_TRUE(io::decodedHere(plain, "p.png", cv::IMREAD_COLOR));
  EXPECT_FALSE(io::decodedHere(plain, "p.png", cv::IMREAD_UNCHANGED));
  expectSame(io::decodeImage(plain, "p.png", cv::IMREAD_UNCHANGED),
             cv::imdecode(plain, cv::IMREAD_UNCHANGED));
  // IDAT chunks split by another chunk: libpng's to judge.
  const Bytes split = pngOf({header(9, 5),
                             {"IDAT", Bytes(rows.begin(), rows.begin() + 10)},
                             {"tEXt", {'k', 0, 'v'}},
                             {"IDAT", Bytes(rows.begin() + 10, rows.end())},
                             {"IEND", {}}});
  EXPECT_FALSE(io::decodedHere(split, "s.png", cv::IMREAD_COLOR));
}

TEST(Image, SizeFromThePngHeaderOrTheDecodedImage) {
  const auto dir = test::scratchDir("image_size");
  const cv::Mat img = noise(17, 11, 5);
  const Bytes png = rgbPng(17, 11, zlibOf(filteredRows(img, [](int) { return 2; })), 1 << 20);
  const auto png_path = (dir / "a.png").string();
  std::ofstream(png_path, std::ios::binary)
      .write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
  EXPECT_EQ(io::imageSize(png_path), std::make_pair(17, 11));
  const auto jpg_path = (dir / "b.jpg").string();
  ASSERT_TRUE(cv::imwrite(jpg_path, img));
  EXPECT_EQ(io::imageSize(jpg_path), std::make_pair(17, 11));
  test::expectError([&] { io::imageSize((dir / "none.png").string()); }, "none.png",
                    "cannot open image");
  std::ofstream(dir / "empty.png").close();  // OpenCV asserts on an empty buffer
  test::expectError([&] { io::readImage((dir / "empty.png").string(), cv::IMREAD_COLOR); },
                    "empty.png", "empty image file");
}
