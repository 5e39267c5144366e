// SPDX-License-Identifier: BSD-3-Clause
// Shared by the fuzz targets (issue #15). Each reader is handed the fuzzer's bytes as a file, the
// way a user's bad file reaches it. A reader may return, or throw cleanmap::Error with one line
// that names the file; anything else (a crash, another exception, a leak, a huge allocation, a
// hang) is a finding. Built two ways: with libFuzzer (`make fuzz`, clang) and with replay_main.cpp,
// which runs the committed corpus through the same target in `make test` (normal and ASan builds).
#pragma once
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <vector>

#include "cleanmap/core/error.h"
#include "cleanmap/core/types.h"

namespace cleanmap::fuzz {

/// A private scratch folder for this process (under $TMPDIR or /tmp), removed at exit.
const std::string& scratchDir();

/// Writes the bytes to scratchDir()/name (sub-folders created) and returns the path.
std::string writeInput(const std::string& name, const uint8_t* data, std::size_t size);
std::string writeInput(const std::string& name, const std::string& text);

/// Aborts (a finding) with `why` and the message.
[[noreturn]] void finding(const std::string& why, const std::string& message);

/// A finding unless every point is finite (readers drop NaN and infinite points, never deliver
/// them).
void requireFinitePoints(const std::vector<PointXYZI>& points, const std::string& path);

/// Runs `fn`. A cleanmap::Error is the expected outcome of bad input: its message must be one
/// line that names `must_name` (the file, or the text's name). Other exceptions escape: a finding.
template <class F>
void expectCleanError(const std::string& must_name, F&& fn) {
  try {
    fn();
  } catch (const cleanmap::Error& e) {
    const std::string m = e.what();
    for (const char c : m)
      if (static_cast<unsigned char>(c) < 0x20)
        finding("control character in the error message", m);
    if (m.find(must_name) == std::string::npos) finding("error does not name " + must_name, m);
  }
}

}  // namespace cleanmap::fuzz
