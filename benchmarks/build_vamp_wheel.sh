#!/usr/bin/env bash
# Build a VAMP wheel (vamp-planner 0.6.4, Kavraki Lab, Apache-2.0) that runs on this CPU, for
# benchmarks/bench_motion.py only (VAMP is never a dependency of the project).
#
# Why: VAMP's CMake compiles with -march=native, so a wheel built on an AVX-512 machine dies
# with SIGILL on an AVX2-only one. This builds the PyPI sdist with -march=x86-64-v3 (AVX2,
# FMA, BMI2) and the robots sphere, ur5 and panda. The sdist's CMake downloads nigh, pdqsort,
# SIMDxorshift and CPM.cmake from GitHub at configure time; where that is not reachable, the
# CPM step is replaced by local stand-ins written below:
#   - nigh (nearest neighbours): an exact linear search with nigh's interface as VAMP uses it
#     (insert, size, clear, nearest(key), nearest(out, key, k, r)): the same neighbours, up
#     to ties, as nigh's k-d tree, at O(n) per query (VAMP's trees on these problems hold
#     tens to hundreds of nodes);
#   - pdqsort: std::sort under pdqsort's names (the same order up to ties);
#   - SIMDxorshift: xorshift128+ on four 64-bit lanes (only VAMP's `xorshift` sampler uses
#     it; the benchmark uses VAMP's Halton sampler);
#   - nanobind: its PyPI package (2.8.0, the version the sdist pins by commit).
# Needs: Debian's libeigen3-dev, a C++17 compiler, cmake >= 3.22 (the sdist's build requires
# the PyPI cmake otherwise), ninja. About 8-15 minutes on 2 busy cores.
#
# Usage: bash benchmarks/build_vamp_wheel.sh [WORKDIR]   (default /tmp/vamp-build)
# then:  .venv/bin/python -m uv pip install --reinstall WORKDIR/dist/vamp_planner-*.whl
set -euo pipefail

ROOT="$(cd "$(dirname "$0")/.." && pwd)"
PY="${PYTHON:-$ROOT/.venv/bin/python}"
WORK="${1:-/tmp/vamp-build}"
DEPS="$WORK/deps"
mkdir -p "$WORK" "$DEPS"
cd "$WORK"

if ! dpkg -s libeigen3-dev >/dev/null 2>&1; then
    apt-get install -y libeigen3-dev || { apt-get update && apt-get install -y libeigen3-dev; }
fi
if [ ! -d vamp_planner-0.6.4 ]; then
    "$PY" -m pip download --no-deps --no-binary vamp-planner vamp-planner==0.6.4 -d .
    tar xzf vamp_planner-0.6.4.tar.gz
fi
SRC="$WORK/vamp_planner-0.6.4"

# ---- stand-ins for the GitHub dependencies -----------------------------------------------
mkdir -p "$DEPS/nigh/src/nigh" "$DEPS/pdqsort" "$DEPS/SIMDxorshift/include" \
    "$DEPS/SIMDxorshift/src"
cat > "$DEPS/nigh/src/nigh/nigh_forward.hpp" <<'EOF'
// Stand-in for nigh's interface as VAMP 0.6.4 uses it (see build_vamp_wheel.sh).
#pragma once
#include <cstddef>
namespace unc::robotics::nigh {
struct NoThreadSafety {};
template <std::size_t batchSize = 8> struct KDTreeBatch {};
namespace metric {
template <int p> struct LP {};
template <typename Type, typename Metric, typename Enabled = void> struct Space;
}  // namespace metric
template <typename T, typename Space, typename KeyFn, typename Concurrency, typename Strategy>
class Nigh;
}  // namespace unc::robotics::nigh
EOF
printf '#pragma once\n#include "nigh_forward.hpp"\n' > "$DEPS/nigh/src/nigh/lp_space.hpp"
cat > "$DEPS/nigh/src/nigh/kdtree_batch.hpp" <<'EOF'
// Exact nearest neighbours by linear search, nigh's calls (see build_vamp_wheel.sh).
#pragma once
#include "nigh_forward.hpp"
#include <algorithm>
#include <limits>
#include <optional>
#include <tuple>
#include <utility>
#include <vector>
namespace unc::robotics::nigh {
template <typename T, typename Space, typename KeyFn, typename Concurrency, typename Strategy>
class Nigh {
  public:
    using Key = typename Space::Type;
    using Distance = typename Space::Distance;
    explicit Nigh(KeyFn keyFn = KeyFn()) : keyFn_(keyFn) {}
    void insert(const T &value) { nodes_.push_back(value); }
    [[nodiscard]] std::size_t size() const { return nodes_.size(); }
    void clear() { nodes_.clear(); }
    std::optional<std::pair<T, Distance>> nearest(const Key &key) const {
        if (nodes_.empty()) return std::nullopt;
        std::size_t best = 0;
        Distance bestDist = std::numeric_limits<Distance>::infinity();
        for (std::size_t i = 0; i < nodes_.size(); ++i) {
            const Distance d = Space::distance(keyFn_(nodes_[i]), key);
            if (d < bestDist) { bestDist = d; best = i; }
        }
        return std::make_pair(nodes_[best], bestDist);
    }
    template <typename Tuple>
    void nearest(std::vector<Tuple> &out, const Key &key, std::size_t k,
                 Distance maxRadius = std::numeric_limits<Distance>::infinity()) const {
        out.clear();
        if (k == 0) return;
        for (const auto &node : nodes_) {
            const Distance d = Space::distance(keyFn_(node), key);
            if (d <= maxRadius) out.emplace_back(node, d);
        }
        auto cmp = [](const Tuple &a, const Tuple &b) { return std::get<1>(a) < std::get<1>(b); };
        if (out.size() > k) {
            std::partial_sort(out.begin(), out.begin() + k, out.end(), cmp);
            out.resize(k);
        } else {
            std::sort(out.begin(), out.end(), cmp);
        }
    }
  private:
    KeyFn keyFn_;
    std::vector<T> nodes_;
};
}  // namespace unc::robotics::nigh
EOF
cat > "$DEPS/pdqsort/pdqsort.h" <<'EOF'
// pdqsort's names over std::sort (see build_vamp_wheel.sh).
#pragma once
#include <algorithm>
template <class I, class C> inline void pdqsort(I b, I e, C c) { std::sort(b, e, c); }
template <class I> inline void pdqsort(I b, I e) { std::sort(b, e); }
template <class I, class C> inline void pdqsort_branchless(I b, I e, C c) { std::sort(b, e, c); }
template <class I> inline void pdqsort_branchless(I b, I e) { std::sort(b, e); }
EOF
cat > "$DEPS/SIMDxorshift/include/simdxorshift128plus.h" <<'EOF'
// xorshift128+ on four 64-bit lanes (see build_vamp_wheel.sh).
#ifndef SIMDXORSHIFT128PLUS_H
#define SIMDXORSHIFT128PLUS_H
#include <stdint.h>
#include <immintrin.h>
typedef struct { __m256i part1; __m256i part2; } avx_xorshift128plus_key_t;
void avx_xorshift128plus_init(uint64_t key1, uint64_t key2, avx_xorshift128plus_key_t *key);
__m256i avx_xorshift128plus(avx_xorshift128plus_key_t *key);
#endif
EOF
cat > "$DEPS/SIMDxorshift/src/simdxorshift128plus.c" <<'EOF'
#include "simdxorshift128plus.h"
/* splitmix64 spreads the two seeds over the lanes' states */
static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}
void avx_xorshift128plus_init(uint64_t key1, uint64_t key2, avx_xorshift128plus_key_t *key) {
    uint64_t a[4], b[4], s = key1 ^ (key2 << 1);
    for (int i = 0; i < 4; ++i) { a[i] = splitmix64(&s) | 1; b[i] = splitmix64(&s) | 1; }
    key->part1 = _mm256_loadu_si256((const __m256i *)a);
    key->part2 = _mm256_loadu_si256((const __m256i *)b);
}
__m256i avx_xorshift128plus(avx_xorshift128plus_key_t *key) {
    __m256i x = key->part1;
    const __m256i y = key->part2;
    key->part1 = y;
    x = _mm256_xor_si256(x, _mm256_slli_epi64(x, 23));
    key->part2 = _mm256_xor_si256(_mm256_xor_si256(x, y),
                                  _mm256_xor_si256(_mm256_srli_epi64(x, 17),
                                                   _mm256_srli_epi64(y, 26)));
    return _mm256_add_epi64(key->part2, y);
}
EOF
: > "$DEPS/SIMDxorshift/src/xorshift128plus.c"

# ---- the sdist's build: local dependencies, AVX2, three robots -----------------------------
[ -f "$SRC/cmake/FetchInitCPM.cmake.orig" ] || cp "$SRC/cmake/FetchInitCPM.cmake" \
    "$SRC/cmake/FetchInitCPM.cmake.orig"
cat > "$SRC/cmake/FetchInitCPM.cmake" <<EOF
# Offline build: CPMAddPackage resolves each dependency to a local source folder; nanobind
# comes from its Python package.
set(VAMP_LOCAL_DEPS "$DEPS")
function(CPMAddPackage spec)
  string(REGEX REPLACE "^gh:[^/]+/([^#]+)#.*\$" "\\\\1" _name "\${spec}")
  if(_name STREQUAL "nanobind")
    execute_process(COMMAND "\${Python_EXECUTABLE}" -m nanobind --cmake_dir
                    OUTPUT_VARIABLE _nb_dir OUTPUT_STRIP_TRAILING_WHITESPACE)
    find_package(nanobind CONFIG REQUIRED PATHS "\${_nb_dir}" NO_DEFAULT_PATH)
  else()
    set(\${_name}_SOURCE_DIR "\${VAMP_LOCAL_DEPS}/\${_name}" PARENT_SCOPE)
    set(\${_name}_ADDED YES PARENT_SCOPE)
  endif()
endfunction()
EOF
"$PY" - "$SRC/pyproject.toml" <<'EOF'
import pathlib, sys
p = pathlib.Path(sys.argv[1])
s = p.read_text()
s = s.replace('wheel.py-api = "cp312"\n', '')
s = s.replace('VAMP_ROBOT_MODULES="sphere;ur5;panda;fetch;baxter"', 'VAMP_ROBOT_MODULES="sphere;ur5;panda"')
s = s.replace('VAMP_ROBOT_STRUCTS="Sphere;UR5;Panda;Fetch;Baxter"',
              'VAMP_ROBOT_STRUCTS="Sphere;UR5;Panda"\nVAMP_ARCH="-march=x86-64-v3"\n'
              'VAMP_INSTALL_CPP_LIBRARY="OFF"')
p.write_text(s)
EOF
echo 'nanobind==2.8.0' > "$WORK/constraints.txt"
cd "$SRC"
PIP_CONSTRAINT="$WORK/constraints.txt" CMAKE_BUILD_PARALLEL_LEVEL="${JOBS:-2}" \
    "$PY" -m pip wheel --no-deps -w "$WORK/dist" .
ls "$WORK"/dist/vamp_planner-0.6.4-*.whl
