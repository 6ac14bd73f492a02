#!/usr/bin/env bash
# The documentation stands alone: every relative link in doc/ and README.md
# points at a file of the repository, every repository path cited in doc/,
# README.md, the help texts (the host's usage, the recipes' descriptions that
# --help prints, the Lua modules' comments) exists, and nothing refers to
# files outside the repository.
cd "$(dirname "$0")/../.." || exit 1
pass() { echo "PASS test_docs: $1"; }
fail() { echo "FAIL test_docs: $1: $2"; }
docs=$(ls README.md doc/*.md doc/api/*.md)
texts="$docs $(ls lua/gradus/*.lua recipes/*.lua engine/*.h)"

# 1. relative markdown links: [text](path) and [text](path#anchor)
bad=""
n=0
for f in $docs; do
  dir=$(dirname "$f")
  while IFS= read -r link; do
    target=${link%%#*}
    case "$target" in http://*|https://*|mailto:*|"") continue ;; esac
    n=$((n + 1))
    [ -e "$dir/$target" ] || bad="$bad $f->$target"
  done < <(grep -oE '\]\([^) ]+\)' "$f" | sed -E 's/^\]\((.*)\)$/\1/')
done
[ "$n" -gt 20 ] && [ -z "$bad" ] && pass "$n relative links resolve" || fail "relative links resolve" "${bad:-only $n links found}"

# 2. repository paths cited anywhere in the texts (globs allowed)
bad=""
n=0
for f in $texts; do
  while IFS= read -r p; do
    p=${p%%[.,:;)]}
    p=${p%%[.,:;)]}
    case "$p" in *'<'*|*KEY*|*NAME*|*/) continue ;; */x.lua) continue ;; esac  # x.lua: the placeholder recipe of messages
    n=$((n + 1))
    # shellcheck disable=SC2086
    compgen -G "$p" >/dev/null || [ -e "$p" ] || bad="$bad $f:$p"
  done < <(grep -oE '(^|[^A-Za-z0-9_./-])(doc|recipes|engine|lua|tests|bench)/[A-Za-z0-9_./*-]+' "$f" |
           sed -E 's/^[^a-z]//')
done
[ "$n" -gt 50 ] && [ -z "$bad" ] && pass "$n cited repository paths exist" || fail "cited repository paths exist" "${bad:-only $n paths found}"

# 3. nothing points outside the repository
out=$(grep -nE 'SPEC\.md|\.\./shared|shared/(paper|SPEC|STYLE|DESIGN)|/work/' $texts 2>/dev/null)
[ -z "$out" ] && pass "no reference outside the repository" || fail "no reference outside the repository" "$out"

# 4. the help texts a user sees: usage and every recipe's --help cite only existing files
G=${GRADUS:-build/gradus}
helps=$($G help 2>&1; for r in recipes/*.lua; do $G run "$r" --help 2>&1; done)
bad=""
while IFS= read -r p; do
  p=${p%%[.,:;)]}
  case "$p" in *'<'*|*/) continue ;; esac
  compgen -G "$p" >/dev/null || [ -e "$p" ] || bad="$bad $p"
done < <(printf '%s\n' "$helps" | grep -oE '(^|[^A-Za-z0-9_./-])(doc|recipes|engine|lua|tests|bench)/[A-Za-z0-9_./*-]+' | sed -E 's/^[^a-z]//')
printf '%s' "$helps" | grep -qE 'SPEC\.md|shared/' && bad="$bad (a help text cites SPEC.md or shared/)"
[ -z "$bad" ] && pass "help texts cite existing files only" || fail "help texts cite existing files only" "$bad"

# 5. the contract is there and is indexed
[ -s doc/contract.md ] && grep -q '(contract.md)' doc/README.md && pass "doc/contract.md indexed" || fail "doc/contract.md indexed" "missing"
for s in "## 3. Graded solids" "Voxel-owned grading" "## 4. Layers" "## 5. Scan vectors" "## 6. Files" "## 7. Command line and recipes" "## 8. Stats"; do
  grep -qF "$s" doc/contract.md || fail "contract section" "$s missing"
done
