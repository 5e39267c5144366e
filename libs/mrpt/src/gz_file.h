// SPDX-License-Identifier: BSD-3-Clause
// Closing an MRPT gzip stream with a check that all of it reached the disk.
#pragma once
#include <mrpt/io/CFileGZOutputStream.h>
#include <cstdint>
#include <fstream>
#include <string>

#include "cleanmap/core/error.h"

namespace cleanmap::mrpt {

/// Closes `gz` (writing `tmp`, to become `path`) and checks the file: MRPT's close() drops
/// gzclose()'s result, so a disk that fills in the last flush would leave a truncated file that
/// looks written. A gzip file ends with the uncompressed size mod 2^32 (RFC 1952, ISIZE): it must
/// equal what was written. Throws cleanmap::Error naming `path` otherwise.
inline void closeGzChecked(::mrpt::io::CFileGZOutputStream& gz, const std::string& tmp,
                           const std::string& path) {
  const auto written = static_cast<uint32_t>(gz.getPosition());  // uncompressed bytes
  gz.close();
  std::ifstream in(tmp, std::ios::binary | std::ios::ate);
  constexpr std::streamoff kHeaderAndTrailer = 18;
  if (!in || in.tellg() < kHeaderAndTrailer) throw Error(path, "write failed (disk full?)");
  unsigned char b[4];
  in.seekg(-4, std::ios::end);
  in.read(reinterpret_cast<char*>(b), 4);
  const uint32_t isize = b[0] | uint32_t(b[1]) << 8 | uint32_t(b[2]) << 16 | uint32_t(b[3]) << 24;
  if (!in || isize != written)
    throw Error(path, "write failed (disk full?): the file is cut short");
}

}  // namespace cleanmap::mrpt
