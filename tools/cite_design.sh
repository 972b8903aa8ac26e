#!/bin/sh
# Points the citations of the old design brief at the project's own design document:
# "DESIGN.md section N" -> "docs/design.md section N" (same section numbers), in the comments
# and prose of every tracked file except docs/results/ and this script. Idempotent: replaced
# citations no longer match. Run from anywhere inside the repository.
set -eu
cd "$(git rev-parse --show-toplevel)"
git ls-files -z | grep -zv -e '^docs/results/' -e '^tools/cite_design\.sh$' -e '^docs/design\.md$' |
  xargs -0 grep -IlZ -e 'DESIGN\.md' -e 'DESIGN sec\.' -- 2>/dev/null |
  xargs -0 -r sed -i \
    -e 's#`/work/shared/DESIGN\.md` §\([0-9]\)#`docs/design.md` section \1#g' \
    -e 's#/work/shared/DESIGN\.md#docs/design.md#g' \
    -e 's#the impulse rule of DESIGN\.md)#the impulse rule of docs/design.md section 5)#g' \
    -e 's#DESIGN\.md#docs/design.md#g' \
    -e 's#DESIGN sec\. #docs/design.md sec. #g'
