#!/usr/bin/env bash
# The README's install, as a user runs it: a venv over the system's packages, then
# `pip install --no-build-isolation .` from a copy of the source tree. The extension module comes from
# the existing build BUILD (FACETREE_CMAKE_BUILD_DIR) so the library is not compiled twice; then the
# installed package (not the build's) runs the example on a shared mesh.
#   install_package.sh BUILD SOURCE MESH
set -euo pipefail
build="$1" source="$2" mesh="$3"
work="$(mktemp -d "${TMPDIR:-/tmp}/facetree-pip.XXXXXX")"
trap 'rm -rf "$work"' EXIT
mkdir "$work/src"
if git -C "$source" rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  git -C "$source" ls-files -co --exclude-standard -z | (cd "$source" && xargs -0 tar -cf - --) | tar -xf - -C "$work/src"
else
  tar -C "$source" --exclude=.git -cf - . | tar -xf - -C "$work/src"
fi
/usr/bin/python3 -m venv --system-site-packages "$work/venv"
FACETREE_CMAKE_BUILD_DIR="$build" "$work/venv/bin/pip" install --no-build-isolation --no-index -q "$work/src"
cd "$work"
installed="$("$work/venv/bin/python" -c 'import facetree; print(facetree.__file__)')"
case "$installed" in
  "$work/venv/"*) ;;
  *) echo "facetree was imported from $installed, not from the venv" >&2; exit 1 ;;
esac
"$work/venv/bin/python" -c 'import facetree, inspect; assert "Builds the face cluster hierarchy" in inspect.getdoc(facetree.build)'
test -f "$(dirname "$installed")/_facetree.pyi" && test -f "$(dirname "$installed")/py.typed"
"$work/venv/bin/python" "$source/examples/colour_by_cut.py" "$mesh" --clusters 32 -o "$work/clusters.ply"
head -c 200 "$work/clusters.ply" | grep -q "property uint8 red"
echo "installed $installed; example wrote $(stat -c %s "$work/clusters.ply") bytes"
