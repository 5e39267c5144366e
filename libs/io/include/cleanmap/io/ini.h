// SPDX-License-Identifier: BSD-3-Clause
// The one ini reader of the project (run parameters, scenario files): `[section]` headers and
// `key = value` lines. A comment starts with `#` or `;` at the start of a line or after a space
// or tab, so values may hold `;` (scenario paths). A key given twice in one section block is an
// error; every error reads "<name>:<line>: what".
#pragma once
#include <functional>
#include <string>

namespace cleanmap::io {

struct IniLine {
  std::string section;  ///< the current section ("" before the first header)
  std::string key, value;
  int line = 0;
};

struct IniHandlers {
  /// A `[section]` header; `line` for messages. Throw (iniError) to refuse it.
  std::function<void(const std::string& section, int line)> section;
  /// A `key = value` line (key and value trimmed, value not empty). Throw to refuse it.
  std::function<void(const IniLine&)> entry;
};

/// Walks `text`; `name` (a file path) prefixes every message.
void parseIni(const std::string& text, const std::string& name, const IniHandlers& on);

/// Throws cleanmap::Error("<name>:<line>", what).
[[noreturn]] void iniError(const std::string& name, int line, const std::string& what);

/// `s` without leading and trailing blanks (space, tab, CR).
std::string trimBlanks(const std::string& s);

}  // namespace cleanmap::io
