// SPDX-License-Identifier: BSD-3-Clause
#pragma once
#include <stdexcept>
#include <string>

namespace cleanmap {

/// Every error cleanmap reports on bad input: one line, "<file>: <what is wrong>". Messages quote
/// the offending input, so `what` is made printable here: control characters (a newline inside a
/// quoted ini line, binary bytes) become '?', and a quote of a huge line is cut to kMaxWhat.
class Error : public std::runtime_error {
 public:
  static constexpr std::size_t kMaxWhat = 300;

  Error(const std::string& file, const std::string& what)
      : std::runtime_error(file.empty() ? printable(what)
                                        : printable(file) + ": " + printable(what)),
        file_(file) {}
  const std::string& file() const { return file_; }

  static std::string printable(const std::string& s) {
    std::string out = s.size() > kMaxWhat ? s.substr(0, kMaxWhat) + "..." : s;
    for (char& c : out)
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
    return out;
  }

 private:
  std::string file_;
};

}  // namespace cleanmap
