// SPDX-License-Identifier: BSD-3-Clause
// PipelineParams <-> ini files (config/cleanmap.ini). Unknown sections or keys are errors.
#pragma once
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cleanmap/core/params.h"

namespace cleanmap::io {

/// Applies the keys of `path` over `params` (defaults = DESIGN values). Throws cleanmap::Error
/// "<file>:<line>: ..." on unknown sections/keys, malformed lines and out-of-range values.
void loadParams(const std::string& path, PipelineParams& params);
/// Applies ini text (same rules; `name` is used in messages).
void parseParams(const std::string& text, const std::string& name, PipelineParams& params);
/// The finite number `text` is (an integer where `integer`), or nullopt with `why` set to
/// "needs a number, got 'x'" / "needs an integer, got 'x'". The one number rule of our ini files.
std::optional<double> parseNumber(const std::string& text, bool integer, std::string& why);
/// Sets the parameter "section.key" from its text (same rules as the ini; no validate()). Throws
/// cleanmap::Error(where, ...) naming the key on an unknown key or a bad value.
void setParam(PipelineParams& params, const std::string& key, const std::string& value,
              const std::string& where);
/// Every parameter as ("section.key", shortest text of its value), in the order toIni writes them.
std::vector<std::pair<std::string, std::string>> paramValues(const PipelineParams& params);
/// Every ini key as "section.key", in the order toIni writes them.
std::vector<std::string> paramKeys();
/// The shortest decimal text that reads back as exactly `v` (0.15, not 0.14999999999999999).
std::string shortestDouble(double v);
/// The ini text of `params` (every key), so a run's parameters can be stored and reloaded.
std::string toIni(const PipelineParams& params);

}  // namespace cleanmap::io
