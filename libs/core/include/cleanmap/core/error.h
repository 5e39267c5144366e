// SPDX-License-Identifier: BSD-3-Clause
#pragma once
#include <stdexcept>
#include <string>

namespace cleanmap {

/// Every error cleanmap reports on bad input: one line, "<file>: <what is wrong>".
class Error : public std::runtime_error {
 public:
  Error(const std::string& file, const std::string& what)
      : std::runtime_error(file.empty() ? what : file + ": " + what), file_(file) {}
  const std::string& file() const { return file_; }

 private:
  std::string file_;
};

}  // namespace cleanmap
