// SPDX-License-Identifier: BSD-3-Clause
// The owner of the test programs' shared precompiled header (tests/CMakeLists.txt,
// CLEANMAP_TEST_PCH): built, never run.
int main() {
  return 0;
}
