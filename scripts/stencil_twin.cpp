// The stencil node addressing of the kernels (crates/rtmpm-cuda/kernels/stencil.cuh), compiled
// for the CPU: for every stencil start the free zone allows (base - 4 bc in -4..5 on each axis)
// and every node (i, j, k) of the 3x3x3 stencil, the three addressings give the same memory index
// (pblock id * 64 + cell): stencil_idx (one neighbour-list read per node), stencil_blocks with
// stencil_row_blocks (RTMPM_G2P_GATHER 1, RTMPM_P2G_NODES 1) and stencil_pairs with
// stencil_pair_plane and stencil_pair_row (RTMPM_G2P_GATHER 2, RTMPM_P2G_NODES 2: node k of a row
// at n[k] + k). Every read of the neighbour list stays in the gblock's 27 entries, and the ids
// are random and large (up to 2^25 - 1 pblocks, the most whose indices fit in 31 bits), so that
// a wrong block or a lost high bit shows. A lane of the warp scatter that does not scatter
// addresses its gblock's first node (scatter_base) whatever base it holds: its reads stay in the
// 27 entries too, where its base itself (0, p2g_particle_zero's) would read other gblocks'
// entries (checked to be caught). Run by scripts/check_stencil_twin.sh (in CI).
#include <algorithm>
#include <cstdio>
#include <random>
#include <vector>
#define __device__
#define __forceinline__ inline
using std::max;
using std::min;
#include "../crates/rtmpm-cuda/kernels/stencil.cuh"

int main() {
    std::mt19937 g(11);
    std::uniform_int_distribution<unsigned> id(0, (1u << 25) - 1);
    long checked = 0, bad = 0;
    // The neighbour list lies in the middle of a larger array marked with a poison value, so
    // that a read outside the gblock's 27 entries gives a poison id (and a wrong index).
    const unsigned poison = 0x7fffffu;
    for (int trial = 0; trial < 40; ++trial) {
        unsigned list[27 * 3];
        for (unsigned& v : list) v = poison;
        unsigned* nbs = list + 27;
        for (int s = 0; s < 27; ++s) nbs[s] = trial == 0 ? (unsigned)s : id(g);
        const int bc[3] = {trial % 5 - 2, 7, -3};  // gblock coordinates (any)
        for (int r0 = -4; r0 <= 5; ++r0)
            for (int r1 = -4; r1 <= 5; ++r1)
                for (int r2 = -4; r2 <= 5; ++r2) {
                    const int base[3] = {4 * bc[0] + r0, 4 * bc[1] + r1, 4 * bc[2] + r2};
                    StencilIdx si = stencil_idx(bc, base);
                    StencilBlocks sb = stencil_blocks(nbs, bc, base);
                    StencilPairs sp = stencil_pairs(nbs, bc, base);
                    for (int i = 0; i < 3; ++i) {
                        int tx = sp.r[0] + i;
                        unsigned plane[4];
                        stencil_pair_plane(sp, tx >= 4, plane);
                        for (int j = 0; j < 3; ++j) {
                            unsigned row[2];
                            stencil_row_blocks(sb, sb.hi[0][i], sb.hi[1][j], row);
                            int ty = sp.r[1] + j;
                            PairRow pr = stencil_pair_row(sp, plane, ty >= 4, ((unsigned)(tx & 3) << 4) | ((unsigned)(ty & 3) << 2));
                            for (int k = 0; k < 3; ++k) {
                                int slot = si.slot[0][i] + si.slot[1][j] + si.slot[2][k];
                                unsigned want = nbs[slot] * 64u + (si.cell[0][i] | si.cell[1][j] | si.cell[2][k]);
                                unsigned blocks = (sb.hi[2][k] ? row[1] : row[0]) * 64u + ((sb.cell[0][i] | sb.cell[1][j]) | sb.cell[2][k]);
                                long long pairs = (long long)pr.n[k] + k;
                                ++checked;
                                if (slot < 0 || slot >= 27 || blocks != want || pairs != (long long)want) {
                                    if (bad < 10)
                                        printf("r (%d, %d, %d) node (%d, %d, %d): slot %d, index %u, blocks %u, pairs %lld\n", r0, r1, r2, i, j, k,
                                               slot, want, blocks, pairs);
                                    ++bad;
                                }
                            }
                        }
                    }
                }
    }
    printf("%ld stencil nodes checked, %ld differ\n", checked, bad);
    long idle = 0, idle_bad = 0, caught = 0;
    {
        // Lanes that do not scatter: the neighbour list in a wide poisoned array (gblock
        // coordinates up to 8 put base 0's pair up to 9 slots a axis, 117 entries, away).
        std::vector<unsigned> wide(27 * 17, poison);
        unsigned* nbs = wide.data() + 27 * 8;
        for (int s = 0; s < 27; ++s) nbs[s] = (unsigned)s;
        // The addressing of `at` reads only the gblock's entries (no poisoned id).
        auto inside = [&](const int bc[3], const int at[3]) {
            StencilBlocks sb = stencil_blocks(nbs, bc, at);
            StencilPairs sp = stencil_pairs(nbs, bc, at);
            StencilIdx si = stencil_idx(bc, at);
            bool ok = true;
            for (int t = 0; t < 8; ++t) ok = ok && sb.id[t] != poison && sp.id[t] != poison;
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    for (int k = 0; k < 3; ++k) {
                        int slot = si.slot[0][i] + si.slot[1][j] + si.slot[2][k];
                        ok = ok && slot >= 0 && slot < 27;
                    }
            return ok;
        };
        const int held[4][3] = {{0, 0, 0}, {-1000, 77, 5}, {1 << 20, -(1 << 20), 3}, {-4, -4, -4}};
        for (int b0 = -8; b0 <= 8; b0 += 2)
            for (int b1 = -8; b1 <= 8; b1 += 4)
                for (int b2 = -7; b2 <= 8; b2 += 5) {
                    const int bc[3] = {b0, b1, b2};
                    for (const auto& base : held) {
                        int at[3];
                        scatter_base(bc, base, false, at);
                        ++idle;
                        bool ok = inside(bc, at) && at[0] == 4 * bc[0] && at[1] == 4 * bc[1] && at[2] == 4 * bc[2];
                        if (!ok) {
                            if (idle_bad < 10) printf("idle lane, gblock (%d, %d, %d): reads outside its row\n", b0, b1, b2);
                            ++idle_bad;
                        }
                        // A lane that scatters keeps its base.
                        scatter_base(bc, base, true, at);
                        if (at[0] != base[0] || at[1] != base[1] || at[2] != base[2]) ++idle_bad;
                    }
                    // The base itself (0) read outside when the gblock is away from the origin:
                    // the check above would catch a scatter that used it.
                    const int zero[3] = {0, 0, 0};
                    if ((b0 > 1 || b1 > 1 || b2 > 1) && !inside(bc, zero)) ++caught;
                }
    }
    printf("%ld idle lanes checked, %ld read outside their gblock's row; base 0 caught reading outside %ld times\n", idle,
           idle_bad, caught);
    return bad != 0 || idle_bad != 0 || caught == 0;
}
