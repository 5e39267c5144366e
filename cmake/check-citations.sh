#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Every "DESIGN §N" cited in the repository names a section heading "§N" of doc/DESIGN.md.
# usage: check-citations.sh SOURCE_DIR
set -uo pipefail
cd "$1" || exit 1
design=doc/DESIGN.md
[[ -f $design ]] || { echo "FAIL: $design is missing"; exit 1; }
files=$( (git ls-files 2>/dev/null || find . -type f -not -path './build*' -not -path './.git/*') |
  grep -Ev '(^|/)build|\.(png|bin|label|rawlog)$')
bad=0 n=0
while read -r cite; do
  [[ -z $cite ]] && continue
  n=$((n + 1))
  sec=${cite#DESIGN §}
  grep -Eq "^#+ §${sec//./\\.}( |$)" "$design" || { echo "FAIL: 'DESIGN §$sec' has no section in $design"; bad=1; }
done < <(grep -hoE 'DESIGN §[0-9][0-9a-z.]*' $files | sed -E 's/\.+$//' | sort -u)
[[ $n -gt 0 ]] || { echo "FAIL: no DESIGN citation found (is the tree there?)"; exit 1; }
[[ $bad -eq 0 ]] && echo "check-citations: $n distinct sections cited, all in $design"
exit $bad
