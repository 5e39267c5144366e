# SPDX-License-Identifier: BSD-3-Clause
# Shared by the app tests (sourced): failure counting and the one-line-error check.
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }

# expect_error RC "<substring>" cmd...: exit code RC, stderr exactly one line holding the substring.
expect_error() {
  local want_rc=$1 want=$2; shift 2
  local err rc
  err=$("$@" 2>&1 >/dev/null); rc=$?
  [[ $rc -eq $want_rc ]] || fail "'$*' exited $rc, expected $want_rc"
  [[ $(printf '%s\n' "$err" | wc -l) -eq 1 ]] || fail "'$*' printed more than one line: $err"
  [[ "$err" == *"$want"* ]] || fail "'$*' said '$err', expected '$want'"
}

# require_dataset DIR: skip the script when DIR is absent (exit 77, which ctest reports as
# Skipped through SKIP_RETURN_CODE), fail when CI=true.
require_dataset() {
  [[ -d $1 ]] && return 0
  if [[ "${CI:-}" == true ]]; then echo "FAIL: dataset missing in CI: $1"; exit 1; fi
  echo "SKIP: $1 not found (set CLEANMAP_DATA_DIR or -DCLEANMAP_SHARED_DATA_DIR)"; exit 77
}

# full_disk KB cmd...: runs cmd with no file of it growing past KB kilobytes (SIGXFSZ ignored):
# its writes then fail as they would on a full disk.
full_disk() {
  local kb=$1; shift
  (trap '' XFSZ; ulimit -f "$kb"; exec "$@")
}

# finish: the script's exit. A passing script removes its scratch folder (an app test writes up to
# 1.5 GB: `make test` must fit a small disk); a failing one keeps it to look at, as does
# CLEANMAP_KEEP_SCRATCH=1.
finish() {
  if (( fails == 0 )) && [[ -z ${CLEANMAP_KEEP_SCRATCH:-} ]]; then rm -rf "$scratch"; fi
  exit $((fails > 0))
}
