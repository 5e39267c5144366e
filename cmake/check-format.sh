#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Fails if a C++ file differs from its clang-format-14 form (the Debian 12 package that
# cmake/install-deps.sh installs; `make format` applies it).
# usage: check-format.sh SOURCE_DIR
set -uo pipefail
cd "$1" || exit 1
command -v clang-format-14 >/dev/null || { echo "FAIL: clang-format-14 not installed (make deps)"; exit 1; }
files=$( (git ls-files '*.cpp' '*.h' 2>/dev/null || find libs apps tests -name '*.cpp' -o -name '*.h') )
[[ -n $files ]] || { echo "FAIL: no C++ files found"; exit 1; }
# One process for every file (one per file took 20 s, mostly start-ups): --dry-run --Werror names
# each file:line it would change and exits non-zero.
report=$(clang-format-14 --style=file --dry-run --Werror $files 2>&1)
rc=$?
bad=$(sed -n 's/^\([^: ]*\):[0-9]*:[0-9]*: error: code should be clang-formatted.*/\1/p' <<<"$report" | sort -u)
if [[ $rc -ne 0 && -z $bad ]]; then
  echo "FAIL: clang-format-14 failed: $(head -1 <<<"$report")"
  exit 1
fi
if [[ -n $bad ]]; then
  echo "FAIL: not formatted (run 'make format'):"
  echo "$bad" | sed 's/^/  /'
  exit 1
fi
echo "check-format: $(echo "$files" | wc -w) files formatted"
