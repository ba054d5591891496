#!/usr/bin/env bash
# Draws each built-in behaviour (behaviours/NAME.bhv) as docs/behaviours/NAME.dot (ev3-behaviour dot)
# and docs/behaviours/NAME.svg (Graphviz dot -Tsvg), as docs/behaviours.md shows them.
#   tools/behaviour/diagrams.sh [--check] [EV3_BEHAVIOUR]
# --check writes nothing and fails naming each drawing that is missing or stale (make test runs it);
# without it the drawings are written (make diagrams). EV3_BEHAVIOUR defaults to build/bin/ev3-behaviour.
set -euo pipefail
cd "$(dirname "$0")/../.."
check=0
if [ "${1:-}" = --check ]; then check=1; shift; fi
bin=${1:-build/bin/ev3-behaviour}
[ -x "$bin" ] || { echo "diagrams: $bin missing: run 'make build' first" >&2; exit 2; }
command -v dot >/dev/null || { echo "diagrams: Graphviz 'dot' missing (make deps installs graphviz)" >&2; exit 2; }
mkdir -p docs/behaviours
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
stale=0
for bhv in behaviours/*.bhv; do
  name=$(basename "$bhv" .bhv)
  "$bin" dot "$bhv" >"$work/$name.dot"
  dot -Tsvg "$work/$name.dot" >"$work/$name.svg"
  for ext in dot svg; do
    if [ $check = 1 ]; then
      if ! cmp -s "$work/$name.$ext" "docs/behaviours/$name.$ext"; then
        echo "diagrams: docs/behaviours/$name.$ext is stale or missing (run: make diagrams)" >&2
        stale=1
      fi
    else
      cp "$work/$name.$ext" "docs/behaviours/$name.$ext"
    fi
  done
done
if [ $check = 1 ]; then
  [ $stale = 0 ] && echo "diagrams: docs/behaviours/*.svg up to date"
  exit $stale
fi
echo "diagrams: wrote docs/behaviours/{$(ls behaviours/*.bhv | xargs -n1 basename | sed 's/\.bhv$//' | paste -sd,)}.{dot,svg}"
