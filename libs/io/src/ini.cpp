// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/ini.h"

#include <set>
#include <sstream>

#include "cleanmap/core/error.h"

namespace cleanmap::io {

std::string trimBlanks(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

void iniError(const std::string& name, int line, const std::string& what) {
  throw Error(name + ":" + std::to_string(line), what);
}

namespace {
// Cuts a comment: `#` or `;` at the start or after a blank.
std::string stripComment(const std::string& line) {
  for (std::size_t i = 0; i < line.size(); ++i)
    if ((line[i] == '#' || line[i] == ';') && (i == 0 || line[i - 1] == ' ' || line[i - 1] == '\t'))
      return line.substr(0, i);
  return line;
}
}  // namespace

void parseIni(const std::string& text, const std::string& name, const IniHandlers& on) {
  std::istringstream in(text);
  std::string raw, section;
  std::set<std::string> seen;  // keys of the current section block
  int lineno = 0;
  while (std::getline(in, raw)) {
    ++lineno;
    const std::string line = trimBlanks(stripComment(raw));
    if (line.empty()) continue;
    if (line.front() == '[') {
      if (line.back() != ']') iniError(name, lineno, "malformed section header '" + line + "'");
      section = trimBlanks(line.substr(1, line.size() - 2));
      seen.clear();
      if (on.section) on.section(section, lineno);
      continue;
    }
    const auto eq = line.find('=');
    if (eq == std::string::npos)
      iniError(name, lineno, "expected 'key = value', got '" + line + "'");
    IniLine e{section, trimBlanks(line.substr(0, eq)), trimBlanks(line.substr(eq + 1)), lineno};
    if (e.key.empty()) iniError(name, lineno, "missing key before '='");
    if (section.empty()) iniError(name, lineno, "key '" + e.key + "' outside any section");
    if (e.value.empty()) iniError(name, lineno, "'" + e.key + "' has an empty value");
    if (!seen.insert(e.key).second)
      iniError(name, lineno, "'" + e.key + "' given twice in [" + section + "]");
    on.entry(e);
  }
}

}  // namespace cleanmap::io
