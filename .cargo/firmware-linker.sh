#!/bin/sh
# The firmware's linker: flip-link (the stack below .data/.bss, so an overflow faults), run from
# an empty directory. A linker script's `INCLUDE memory.x` looks in the current directory before
# the search path; from the repository's top level, whose memory.x is the default board's, every
# other board would link that map. From here the selected board's map, which build.rs puts on
# the search path, is the one found. Every path rustc passes is absolute.
dir=$(mktemp -d) || exit 1
trap 'rm -rf "$dir"' EXIT
cd "$dir" || exit 1
flip-link "$@"
