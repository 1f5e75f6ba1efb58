#!/bin/bash
# Pack Warp and the wheels a lent GPU machine lacks (its image has Python 3.12, numpy, scipy, matplotlib, pytest,
# hypothesis, but no Warp or pydantic) into two parts under .wp/ and .wp2/ (both in .git/info/exclude), each small
# enough to travel with the tree (64 MiB a call, docs/ left out: benchmarks/README.md, "On a GPU").
set -euo pipefail
work=$(mktemp -d)
pin() { grep -i "^$1==" constraints.txt; }
plat=(--platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64)
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp "${plat[@]}" \
    -d "$work/wheels" "$(pin warp-lang)" "$(pin pydantic)" "$(pin pydantic_core)" "$(pin annotated-types)" \
    "$(pin typing-inspection)" "$(pin typing_extensions)" "$(pin trimesh)" "$(pin magpylib)" "$(pin dask)" \
    "$(pin distributed)" "$(pin partd)" "$(pin locket)" "$(pin zict)" "$(pin tblib)"
# Warp's wheel (150 MB) is too big for one call: its two libraries xz-compressed (78 + 19 MB), its Python apart
mkdir -p "$work/x" "$work/bundle/deps"
unzip -q "$work"/wheels/warp_lang-*.whl -d "$work/x"
mv "$work"/wheels/*.whl "$work/bundle/deps/" && rm "$work"/bundle/deps/warp_lang-*.whl
xz -9 -T2 -c "$work/x/warp/bin/warp.so" > "$work/bundle/warp.so.xz"
xz -9 -T2 -c "$work/x/warp/bin/warp-clang.so" > "$work/bundle/warp-clang.so.xz"
tar --exclude=warp/examples --exclude=warp/tests --exclude=warp/bin -C "$work/x" -cJf "$work/bundle/warp-py.tar.xz" \
    warp $(cd "$work/x" && ls -d warp_lang-*.dist-info)
rm -rf .wp .wp2 && mkdir -p .wp .wp2
tar cf "$work/b.tar" -C "$work/bundle" . && split -n 2 -d "$work/b.tar" .wp/part-
mv .wp/part-01 .wp2/
rm -rf "$work"
ls -la .wp .wp2
