// SPDX-License-Identifier: MIT
#include "kernels/pool2d.h"

#include <algorithm>
#include <cmath>

namespace g2l::kernels {

namespace {

// The in-image part [lo, hi) of window o along one axis of size n (kernel k, stride s, pad p).
struct Span {
    int64_t lo, hi;
};
Span window(int64_t o, int64_t k, int64_t s, int64_t p, int64_t n) {
    const int64_t start = o * s - p;
    return {std::max<int64_t>(start, 0), std::min(start + k, n)};
}

}  // namespace

template <class T>
void max_pool2d_fwd_cpu(const T* x, T* y, int32_t* argmax, const Pool2dGeom& g) {
    const int64_t planes = g.B * g.C, HW = g.H * g.W, P = g.Ho * g.Wo;
    // One (b, c) plane per iteration: every output element is computed by one thread.
#pragma omp parallel for schedule(static)
    for (int64_t pl = 0; pl < planes; ++pl) {
        const T* xp = x + pl * HW;
        for (int64_t oh = 0; oh < g.Ho; ++oh) {
            const Span sh = window(oh, g.kh, g.sh, g.ph, g.H);
            for (int64_t ow = 0; ow < g.Wo; ++ow) {
                const Span sw = window(ow, g.kw, g.sw, g.pw, g.W);
                // Every window overlaps the image (the op enforces padding <= kernel / 2), so
                // the window's first in-image element is a valid start.
                int64_t best_i = sh.lo * g.W + sw.lo;
                T best = xp[best_i];
                // Strictly greater keeps the first of equal values; a NaN takes over once and
                // then stays, since nothing compares greater than it.
                for (int64_t ih = sh.lo; ih < sh.hi; ++ih) {
                    for (int64_t iw = sw.lo; iw < sw.hi; ++iw) {
                        const T v = xp[ih * g.W + iw];
                        if (v > best || (std::isnan(v) && !std::isnan(best))) {
                            best = v;
                            best_i = ih * g.W + iw;
                        }
                    }
                }
                y[pl * P + oh * g.Wo + ow] = best;
                argmax[pl * P + oh * g.Wo + ow] = int32_t(best_i);
            }
        }
    }
}

template <class T>
void max_pool2d_bwd_cpu(const T* dy, const int32_t* argmax, T* dx, const Pool2dGeom& g) {
    const int64_t planes = g.B * g.C, HW = g.H * g.W, P = g.Ho * g.Wo;
#pragma omp parallel for schedule(static)
    for (int64_t pl = 0; pl < planes; ++pl) {
        T* dxp = dx + pl * HW;
        std::fill(dxp, dxp + HW, T(0));
        // Overlapping windows (stride < kernel) can pick the same input: within a plane the
        // adds run in output order on one thread.
        for (int64_t q = 0; q < P; ++q) dxp[argmax[pl * P + q]] += dy[pl * P + q];
    }
}

template <class T>
void avg_pool2d_fwd_cpu(const T* x, T* y, const Pool2dGeom& g, bool count_include_pad) {
    const int64_t planes = g.B * g.C, HW = g.H * g.W, P = g.Ho * g.Wo;
#pragma omp parallel for schedule(static)
    for (int64_t pl = 0; pl < planes; ++pl) {
        const T* xp = x + pl * HW;
        for (int64_t oh = 0; oh < g.Ho; ++oh) {
            const Span sh = window(oh, g.kh, g.sh, g.ph, g.H);
            for (int64_t ow = 0; ow < g.Wo; ++ow) {
                const Span sw = window(ow, g.kw, g.sw, g.pw, g.W);
                T s = T(0);
                for (int64_t ih = sh.lo; ih < sh.hi; ++ih)
                    for (int64_t iw = sw.lo; iw < sw.hi; ++iw) s += xp[ih * g.W + iw];
                // count_include_pad (PyTorch's default) divides by the full window even where it
                // overlaps the padding; otherwise by the in-image part, which is never empty.
                const int64_t div =
                    count_include_pad ? g.kh * g.kw : (sh.hi - sh.lo) * (sw.hi - sw.lo);
                y[pl * P + oh * g.Wo + ow] = s / T(div);
            }
        }
    }
}

template <class T>
void avg_pool2d_bwd_cpu(const T* dy, T* dx, const Pool2dGeom& g, bool count_include_pad) {
    const int64_t planes = g.B * g.C, HW = g.H * g.W, P = g.Ho * g.Wo;
#pragma omp parallel for schedule(static)
    for (int64_t pl = 0; pl < planes; ++pl) {
        T* dxp = dx + pl * HW;
        // Zeroed because overlapping windows add into the same inputs below.
        std::fill(dxp, dxp + HW, T(0));
        for (int64_t oh = 0; oh < g.Ho; ++oh) {
            const Span sh = window(oh, g.kh, g.sh, g.ph, g.H);
            for (int64_t ow = 0; ow < g.Wo; ++ow) {
                const Span sw = window(ow, g.kw, g.sw, g.pw, g.W);
                const int64_t div =
                    count_include_pad ? g.kh * g.kw : (sh.hi - sh.lo) * (sw.hi - sw.lo);
                const T d = dy[pl * P + oh * g.Wo + ow] / T(div);
                for (int64_t ih = sh.lo; ih < sh.hi; ++ih)
                    for (int64_t iw = sw.lo; iw < sw.hi; ++iw) dxp[ih * g.W + iw] += d;
            }
        }
    }
}

template void max_pool2d_fwd_cpu<float>(const float*, float*, int32_t*, const Pool2dGeom&);
template void max_pool2d_fwd_cpu<double>(const double*, double*, int32_t*, const Pool2dGeom&);
template void max_pool2d_bwd_cpu<float>(const float*, const int32_t*, float*, const Pool2dGeom&);
template void max_pool2d_bwd_cpu<double>(const double*, const int32_t*, double*,
                                         const Pool2dGeom&);
template void avg_pool2d_fwd_cpu<float>(const float*, float*, const Pool2dGeom&, bool);
template void avg_pool2d_fwd_cpu<double>(const double*, double*, const Pool2dGeom&, bool);
template void avg_pool2d_bwd_cpu<float>(const float*, float*, const Pool2dGeom&, bool);
template void avg_pool2d_bwd_cpu<double>(const double*, double*, const Pool2dGeom&, bool);

}  // namespace g2l::kernels
