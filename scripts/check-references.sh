#!/usr/bin/env bash
# Fails when a comment or a document of the repository cites what a reader of
# the repository cannot follow: the design and style documents that lived
# outside it (DESIGN.md, STYLE.md; their content is now in docs/ and the
# README), an issue tracker's numbers ("issue 14", "issues 10, 15",
# "Issue-3", "issue #7"), or the "contract §N" of an issue. Comments cite the
# project's own documents by file and section heading and the thesis by its
# section and equation numbers (docs/ARCHITECTURE.md, "Where the design
# lives"). A link to a third-party project's issue (…/issues/123) is not a
# citation of ours and is not flagged.
#
#   scripts/check-references.sh [ROOT]      default: the repository root
#
# Searches every text file under ROOT except build trees (build*/), .git,
# node_modules, Python caches and this script; prints each offending
# line as FILE:LINE:TEXT and exits 1 if there is any, 0 otherwise.
set -euo pipefail

if [[ ${1:-} == --help || ${1:-} == -h ]]; then
  sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
  exit 0
fi

root=${1:-"$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"}
cd "$root"

# What is forbidden, as one extended regular expression.
pattern='DESIGN\.md|STYLE\.md|\b[Ii]ssues?[ -]?#?[0-9]+|\bcontract §[0-9]'

hits=$(grep -rnIE "$pattern" . \
  --exclude-dir='build*' --exclude-dir=.git --exclude-dir=node_modules \
  --exclude-dir=__pycache__ --exclude-dir='*.egg-info' \
  --exclude=check-references.sh || true)
if [[ -n $hits ]]; then
  echo "Citations a reader of the repository cannot follow (cite docs/ or the thesis instead;"
  echo "docs/ARCHITECTURE.md, \"Where the design lives\"):"
  echo "$hits"
  exit 1
fi
echo "check-references: no citation of an outside design document or an issue number"
