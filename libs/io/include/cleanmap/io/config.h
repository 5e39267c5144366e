// SPDX-License-Identifier: BSD-3-Clause
// PipelineParams <-> ini files (config/cleanmap.ini). Unknown sections or keys are errors.
#pragma once
#include <string>

#include "cleanmap/core/params.h"

namespace cleanmap::io {

/// Applies the keys of `path` over `params` (defaults = SPEC values). Throws cleanmap::Error
/// "<file>:<line>: ..." on unknown sections/keys, malformed lines and out-of-range values.
void loadParams(const std::string& path, PipelineParams& params);
/// Applies ini text (same rules; `name` is used in messages).
void parseParams(const std::string& text, const std::string& name, PipelineParams& params);
/// The ini text of `params` (every key), so a run's parameters can be stored and reloaded.
std::string toIni(const PipelineParams& params);
/// Checks physical sense (positive sizes, r_inf <= r_sup <= 1, ...); throws naming the key.
void validate(const PipelineParams& params, const std::string& name);

}  // namespace cleanmap::io
