// SPDX-License-Identifier: MIT
#include "kernels/conv2d.h"

#include <Eigen/Core>
#include <algorithm>
#include <memory>
#include <vector>

#include "kernels/cpu_util.h"

namespace g2l::kernels {

namespace {

template <class T>
using RowMat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
template <class T>
using CMap = Eigen::Map<const RowMat<T>, 0, Eigen::OuterStride<>>;
template <class T>
using MMap = Eigen::Map<RowMat<T>, 0, Eigen::OuterStride<>>;
using Stride = Eigen::OuterStride<>;

// Work-piece sizes. They depend only on the shapes (never on the thread count), so every output
// element is always computed by the same sequence of floating-point operations. All GEMMs run
// inside our own OpenMP regions, where Eigen does not parallelise again (it checks
// omp_get_num_threads() > 1), so each Eigen product is sequential with fixed blocking.
constexpr int64_t kFwdColBytes = 512 * 1024;       // forward im2col tile (stays in L2)
constexpr int64_t kBwdColBytes = 16 * 1024 * 1024;  // backward im2col / dcol slab
constexpr int64_t kRowBlock = 32;                   // dw tiles: rows (output channels)
constexpr int64_t kColBlock = 256;                  // dw tiles: columns; dcol GEMM column tiles

// Columns per tile when a column of the im2col matrix holds `rows` values of `tsize` bytes.
int64_t tile_cols(int64_t budget, int64_t rows, int64_t tsize, int64_t P) {
    const int64_t c = std::max<int64_t>(16, (budget / (rows * tsize)) / 16 * 16);
    return std::min(c, P);
}

// A 1x1 kernel with unit stride and no padding reads x itself as the im2col matrix.
bool is_direct(const Conv2dGeom& g) {
    return g.kh == 1 && g.kw == 1 && g.sh == 1 && g.sw == 1 && g.ph == 0 && g.pw == 0;
}

// Walks columns [p0, p0 + n) of im2col row r = (c * kh + i) * kw + j of one group. Column
// p = oh * Wo + ow reads x[c, ih, iw], ih = oh*sh - ph + i*dh, iw = ow*sw - pw + j*dw. For each
// run of in-image columns it calls valid(q, count, xoff): columns q .. q+count-1 map to the
// group-relative x offsets xoff + k*sw; for each run in the padding it calls pad(q, count).
template <class Valid, class Pad>
void walk_row(const Conv2dGeom& g, int64_t r, int64_t p0, int64_t n, Valid&& valid, Pad&& pad) {
    const int64_t j = r % g.kw, i = (r / g.kw) % g.kh, c = r / (g.kw * g.kh);
    const int64_t off_h = i * g.dh - g.ph, off_w = j * g.dw - g.pw;
    // Output columns ow in [ow_lo, ow_hi) have 0 <= ow*sw + off_w < W.
    const int64_t ow_lo = off_w >= 0 ? 0 : ceil_div(-off_w, g.sw);
    const int64_t ow_hi = off_w > g.W - 1 ? 0 : std::min(g.Wo, (g.W - 1 - off_w) / g.sw + 1);
    int64_t q = 0, p = p0;
    while (q < n) {
        const int64_t oh = p / g.Wo, a = p % g.Wo, b = std::min(g.Wo, a + (n - q));
        const int64_t ih = oh * g.sh + off_h;
        if (ih < 0 || ih >= g.H) {
            pad(q, b - a);
        } else {
            const int64_t lo = std::clamp(ow_lo, a, b), hi = std::clamp(ow_hi, lo, b);
            if (lo > a) pad(q, lo - a);
            if (hi > lo) valid(q + lo - a, hi - lo, (c * g.H + ih) * g.W + lo * g.sw + off_w);
            if (b > hi) pad(q + hi - a, b - hi);
        }
        q += b - a;
        p += b - a;
    }
}

// out[q] = im2col[r, p0 + q] for q < n; xg is one group's input [Cin_g, H, W].
template <class T>
void im2col_row(const T* xg, const Conv2dGeom& g, int64_t r, int64_t p0, int64_t n, T* out) {
    const int64_t s = g.sw;
    walk_row(
        g, r, p0, n,
        [&](int64_t q, int64_t cnt, int64_t xo) {
            if (s == 1) {
                std::copy(xg + xo, xg + xo + cnt, out + q);
            } else {
                for (int64_t k = 0; k < cnt; ++k) out[q + k] = xg[xo + k * s];
            }
        },
        [&](int64_t q, int64_t cnt) { std::fill(out + q, out + q + cnt, T(0)); });
}

// The adjoint of im2col_row: dxg[...] += in[q] for every in-image column (padding is dropped).
template <class T>
void col2im_row(const T* in, const Conv2dGeom& g, int64_t r, int64_t p0, int64_t n, T* dxg) {
    const int64_t s = g.sw;
    walk_row(
        g, r, p0, n,
        [&](int64_t q, int64_t cnt, int64_t xo) {
            for (int64_t k = 0; k < cnt; ++k) dxg[xo + k * s] += in[q + k];
        },
        [](int64_t, int64_t) {});
}

// dbias[co] = sum_{b, p} dy[b, co, p]: one output per loop index, summed in a fixed order.
template <class T>
void bias_grad(const T* dy, T* dbias, const Conv2dGeom& g) {
    const int64_t P = g.Ho * g.Wo;
#pragma omp parallel for schedule(static)
    for (int64_t co = 0; co < g.Cout; ++co) {
        T s = T(0);
        for (int64_t b = 0; b < g.B; ++b) {
            const T* d = dy + (b * g.Cout + co) * P;
            for (int64_t p = 0; p < P; ++p) s += d[p];
        }
        dbias[co] = s;
    }
}

// dw_g [Cout_g, K] = sum_b dy_g [Cout_g, P] * col_g^T [P, K], slab by slab of columns. The
// slabs are visited in order; inside a slab, fixed [kRowBlock x kColBlock] tiles of dw are
// independent tasks, so the sum over (b, slab) per element has a fixed order.
template <class T>
void weight_grad(const T* x, const T* dy, T* dw, const Conv2dGeom& g) {
    const int64_t cin_g = g.Cin / g.groups, cout_g = g.Cout / g.groups;
    const int64_t K = cin_g * g.kh * g.kw, P = g.Ho * g.Wo, HW = g.H * g.W;
    const bool direct = is_direct(g);
    const int64_t nb = tile_cols(kBwdColBytes, g.groups * K, int64_t(sizeof(T)), P);
    const int64_t n_rb = ceil_div(cout_g, kRowBlock), n_cb = ceil_div(K, kColBlock);
    const int64_t n_tasks = g.groups * n_rb * n_cb;
    // Zeroed because the tiles below accumulate (+=) over images and column slabs.
    std::fill(dw, dw + g.Cout * K, T(0));
    // Direct 1x1: x already is the column matrix, so no im2col buffer is needed.
    std::vector<T> col(direct ? 0 : size_t(g.groups * K * nb));
    for (int64_t b = 0; b < g.B; ++b) {
        for (int64_t p0 = 0; p0 < P; p0 += nb) {
            const int64_t n = std::min(nb, P - p0);
            if (!direct) {
                // im2col only copies (no arithmetic), one row per iteration: the split cannot
                // change results.
#pragma omp parallel for schedule(static)
                for (int64_t rr = 0; rr < g.groups * K; ++rr) {
                    const T* xg = x + (b * g.Cin + (rr / K) * cin_g) * HW;
                    im2col_row(xg, g, rr % K, p0, n, col.data() + rr * n);
                }
            }
            // Dynamic scheduling is safe for determinism: a tile's arithmetic is the same whichever
            // thread runs it, and no two tasks write the same dw element.
#pragma omp parallel for schedule(dynamic, 1)
            for (int64_t t = 0; t < n_tasks; ++t) {
                const int64_t gi = t / (n_rb * n_cb), r0 = (t / n_cb) % n_rb * kRowBlock;
                const int64_t c0 = t % n_cb * kColBlock;
                const int64_t m = std::min(kRowBlock, cout_g - r0), k = std::min(kColBlock, K - c0);
                const CMap<T> dym(dy + (b * g.Cout + gi * cout_g + r0) * P + p0, m, n, Stride(P));
                const CMap<T> colm =
                    direct ? CMap<T>(x + (b * g.Cin + gi * cin_g + c0) * HW + p0, k, n, Stride(HW))
                           : CMap<T>(col.data() + (gi * K + c0) * n, k, n, Stride(n));
                MMap<T> dwm(dw + (gi * cout_g + r0) * K + c0, m, k, Stride(K));
                dwm.noalias() += dym * colm.transpose();
            }
        }
    }
}

// dx: dcol_g [K, n] = w_g^T [K, Cout_g] * dy_g [Cout_g, n] per slab of columns (independent
// column tiles), then col2im adds dcol into dx with one task per input channel (each channel's
// rows touch only that channel), so every dx element is summed in a fixed order.
template <class T>
void input_grad(const T* w, const T* dy, T* dx, const Conv2dGeom& g) {
    const int64_t cin_g = g.Cin / g.groups, cout_g = g.Cout / g.groups;
    const int64_t K = cin_g * g.kh * g.kw, P = g.Ho * g.Wo, HW = g.H * g.W;
    const bool direct = is_direct(g);
    const int64_t nb = direct ? P : tile_cols(kBwdColBytes, g.groups * K, int64_t(sizeof(T)), P);
    const int64_t khw = g.kh * g.kw;
    // Zeroed because col2im adds overlapping windows into dx.
    std::fill(dx, dx + g.B * g.Cin * HW, T(0));
    std::vector<T> dcol(direct ? 0 : size_t(g.groups * K * nb));
    for (int64_t b = 0; b < g.B; ++b) {
        for (int64_t p0 = 0; p0 < P; p0 += nb) {
            const int64_t n = std::min(nb, P - p0), n_sub = ceil_div(n, kColBlock);
#pragma omp parallel for schedule(dynamic, 1)
            for (int64_t t = 0; t < g.groups * n_sub; ++t) {
                const int64_t gi = t / n_sub, s0 = t % n_sub * kColBlock;
                const int64_t m = std::min(kColBlock, n - s0);
                const CMap<T> wm(w + gi * cout_g * K, cout_g, K, Stride(K));
                const CMap<T> dym(dy + (b * g.Cout + gi * cout_g) * P + p0 + s0, cout_g, m,
                                  Stride(P));
                // Direct 1x1: each x pixel is exactly one column, so write dx itself.
                MMap<T> out = direct
                                  ? MMap<T>(dx + (b * g.Cin + gi * cin_g) * HW + p0 + s0, K, m,
                                            Stride(HW))
                                  : MMap<T>(dcol.data() + gi * K * n + s0, K, m, Stride(n));
                // Assignment, not +=: dcol is rebuilt per slab, and in the direct case each dx
                // pixel is exactly one column, visited once.
                out.noalias() = wm.transpose() * dym;
            }
            if (direct) continue;
#pragma omp parallel for schedule(static)
            for (int64_t ci = 0; ci < g.Cin; ++ci) {
                const int64_t gi = ci / cin_g, c = ci % cin_g;
                T* dxg = dx + (b * g.Cin + gi * cin_g) * HW;
                for (int64_t r = c * khw; r < (c + 1) * khw; ++r)
                    col2im_row(dcol.data() + (gi * K + r) * n, g, r, p0, n, dxg);
            }
        }
    }
}

}  // namespace

// Forward: tasks are (image, group, column tile); each im2col's its tile into a per-thread
// buffer [K, nc] and runs y_tile [Cout_g, nc] = w_g [Cout_g, K] * col [K, nc] (Eigen GEBP).
template <class T>
void conv2d_fwd_cpu(const T* x, const T* w, const T* bias, T* y, const Conv2dGeom& g) {
    const int64_t cin_g = g.Cin / g.groups, cout_g = g.Cout / g.groups;
    const int64_t K = cin_g * g.kh * g.kw, P = g.Ho * g.Wo, HW = g.H * g.W;
    const bool direct = is_direct(g);
    int64_t nc = tile_cols(kFwdColBytes, K, int64_t(sizeof(T)), P);
    int64_t n_chunks = ceil_div(P, nc);
    // A small problem (an inference's one image, few tiles) is cut into a multiple of 4 tiles of
    // about equal width, so 2 or 4 threads finish together (tiles of 2416 + 2416 + 1 ... left a
    // thread idle for most of a layer at the detector's 1/8 and 1/16 maps). From the shapes only.
    if (g.B * g.groups * n_chunks < 16 && P >= 64) {
        n_chunks = (n_chunks + 3) / 4 * 4;
        nc = (ceil_div(P, n_chunks) + 15) / 16 * 16;
        n_chunks = ceil_div(P, nc);
    }
    const int64_t n_tasks = g.B * g.groups * n_chunks;
#pragma omp parallel
    {
        // One im2col buffer per thread, reused across its tasks rather than allocated per task,
        // and not zeroed: im2col writes every element of a tile (the padding as zeros) before
        // the product reads it (zeroing 512 KB per thread and layer was ~5 % of the detector).
        std::unique_ptr<T[]> col(direct ? nullptr : new T[size_t(K * nc)]);
#pragma omp for schedule(dynamic, 1)
        for (int64_t t = 0; t < n_tasks; ++t) {
            const int64_t ch = t % n_chunks, gi = (t / n_chunks) % g.groups;
            const int64_t b = t / (n_chunks * g.groups);
            const int64_t p0 = ch * nc, n = std::min(nc, P - p0);
            const T* xg = x + (b * g.Cin + gi * cin_g) * HW;
            const CMap<T> wm(w + gi * cout_g * K, cout_g, K, Stride(K));
            MMap<T> ym(y + (b * g.Cout + gi * cout_g) * P + p0, cout_g, n, Stride(P));
            if (direct) {
                ym.noalias() = wm * CMap<T>(xg + p0, K, n, Stride(HW));
            } else {
                for (int64_t r = 0; r < K; ++r) im2col_row(xg, g, r, p0, n, col.get() + r * n);
                ym.noalias() = wm * CMap<T>(col.get(), K, n, Stride(n));
            }
            if (bias) {
                for (int64_t co = 0; co < cout_g; ++co)
                    ym.row(co).array() += bias[gi * cout_g + co];
            }
        }
    }
}

template <class T>
void conv2d_bwd_cpu(const T* x, const T* w, const T* dy, T* dx, T* dw, T* dbias,
                    const Conv2dGeom& g) {
    if (dbias) bias_grad(dy, dbias, g);
    if (dw) weight_grad(x, dy, dw, g);
    if (dx) input_grad(w, dy, dx, g);
}

template void conv2d_fwd_cpu<float>(const float*, const float*, const float*, float*,
                                    const Conv2dGeom&);
template void conv2d_fwd_cpu<double>(const double*, const double*, const double*, double*,
                                     const Conv2dGeom&);
template void conv2d_bwd_cpu<float>(const float*, const float*, const float*, float*, float*,
                                    float*, const Conv2dGeom&);
template void conv2d_bwd_cpu<double>(const double*, const double*, const double*, double*,
                                     double*, double*, const Conv2dGeom&);

}  // namespace g2l::kernels
