// SPDX-License-Identifier: BSD-3-Clause
// Camera images from files (KITTI's image_2 / image_02 PNGs, DESIGN §3): read once, checked whole,
// decoded. A cut or corrupt file is one cleanmap::Error line naming it, never a codec's own output.
#pragma once
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace cleanmap::io {

/// The image in `bytes` (the file `path`'s content), as cv::imdecode(bytes, flags) decodes it.
/// A PNG's chunks are walked to IEND first, each whole and its CRC-32 right; an 8-bit RGB PNG
/// without interlacing or colour-changing chunks (KITTI's) read as cv::IMREAD_COLOR is decoded
/// here (libdeflate and the PNG row filters, the same pixels in about half the time: issue #16),
/// every other image by OpenCV. Throws cleanmap::Error naming `path`: "truncated PNG image",
/// "corrupt PNG image (...)", "cannot decode image".
cv::Mat decodeImage(const std::vector<unsigned char>& bytes, const std::string& path, int flags);

/// Whether decodeImage decodes `bytes` itself (an 8-bit RGB PNG as above) rather than through
/// OpenCV. Throws as decodeImage for a cut or corrupt PNG.
bool decodedHere(const std::vector<unsigned char>& bytes, const std::string& path, int flags);

/// decodeImage of the file's content; "cannot open image" / "cannot read image" where it fails.
cv::Mat readImage(const std::string& path, int flags);

/// {width, height} of the image file: a PNG's from its header once its chunks are checked (as
/// decodeImage does), any other by decoding it.
std::pair<int, int> imageSize(const std::string& path);

}  // namespace cleanmap::io
