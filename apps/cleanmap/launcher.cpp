// SPDX-License-Identifier: BSD-3-Clause
// The `cleanmap` command (issue #16): sets glibc's huge-page tunable (cli::setHugePageTunable),
// read only when a process starts, and executes the app itself, cleanmap-run, from its own
// directory. It links no MRPT library, so MRPT's 181 are loaded once a run instead of twice (by
// an app that re-executes itself): 0.1 s of wall a run (doc/BENCHMARK.md, nineteenth session).
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>

#include "../common/cli.h"

int main(int argc, char** argv) {
  (void)argc;
  const std::string dir = cleanmap::cli::executableDir();
  const std::string app = (dir.empty() ? std::string("./") : dir) + "cleanmap-run";
  cleanmap::cli::setHugePageTunable();
  execv(app.c_str(), argv);
  std::fprintf(stderr, "cleanmap: cannot run %s: %s\n", app.c_str(), std::strerror(errno));
  return 127;
}
