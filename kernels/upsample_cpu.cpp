// SPDX-License-Identifier: MIT
#include "kernels/upsample.h"

#include <algorithm>

namespace g2l::kernels {

namespace {

// Source taps of output index o along one axis (input size n, output size no), PyTorch's
// area_pixel_compute_source_index for linear modes.
template <class T>
struct Tap {
    int64_t i0, i1;
    T w0, w1;
};

template <class T>
Tap<T> tap(int64_t o, int64_t n, int64_t no, bool align_corners) {
    T src;
    if (align_corners) {
        const T scale = no > 1 ? T(n - 1) / T(no - 1) : T(0);
        src = scale * T(o);
    } else {
        const T scale = T(n) / T(no);
        // Half-pixel centres; negative source coordinates (first outputs) clamp to 0, as PyTorch.
        src = std::max(scale * (T(o) + T(0.5)) - T(0.5), T(0));
    }
    const int64_t i0 = std::min(int64_t(src), n - 1);
    const T f = src - T(i0);
    // At the last row / column both taps point at i0, so nothing past the edge is read.
    return {i0, i0 < n - 1 ? i0 + 1 : i0, T(1) - f, f};
}

}  // namespace

template <class T>
void upsample_nearest2d_fwd_cpu(const T* x, T* y, int64_t planes, int64_t H, int64_t W,
                                int64_t s) {
    const int64_t Wo = W * s, HWo = H * s * Wo;
#pragma omp parallel for schedule(static)
    for (int64_t pl = 0; pl < planes; ++pl) {
        for (int64_t oh = 0; oh < H * s; ++oh) {
            const T* xr = x + (pl * H + oh / s) * W;
            T* yr = y + pl * HWo + oh * Wo;
            for (int64_t ow = 0; ow < Wo; ++ow) yr[ow] = xr[ow / s];
        }
    }
}

template <class T>
void upsample_nearest2d_bwd_cpu(const T* dy, T* dx, int64_t planes, int64_t H, int64_t W,
                                int64_t s) {
    const int64_t Wo = W * s, HWo = H * s * Wo;
    // One plane per thread: the scatter-adds of a plane run in output order on one thread.
#pragma omp parallel for schedule(static)
    for (int64_t pl = 0; pl < planes; ++pl) {
        T* dxp = dx + pl * H * W;
        std::fill(dxp, dxp + H * W, T(0));
        for (int64_t oh = 0; oh < H * s; ++oh) {
            const T* dyr = dy + pl * HWo + oh * Wo;
            T* dxr = dxp + (oh / s) * W;
            for (int64_t ow = 0; ow < Wo; ++ow) dxr[ow / s] += dyr[ow];
        }
    }
}

template <class T>
void upsample_bilinear2d_fwd_cpu(const T* x, T* y, int64_t planes, int64_t H, int64_t W,
                                 int64_t Ho, int64_t Wo, bool align_corners) {
#pragma omp parallel for schedule(static)
    for (int64_t pl = 0; pl < planes; ++pl) {
        const T* xp = x + pl * H * W;
        for (int64_t oh = 0; oh < Ho; ++oh) {
            const Tap<T> th = tap<T>(oh, H, Ho, align_corners);
            const T* r0 = xp + th.i0 * W;
            const T* r1 = xp + th.i1 * W;
            T* yr = y + (pl * Ho + oh) * Wo;
            for (int64_t ow = 0; ow < Wo; ++ow) {
                const Tap<T> tw = tap<T>(ow, W, Wo, align_corners);
                yr[ow] = th.w0 * (tw.w0 * r0[tw.i0] + tw.w1 * r0[tw.i1]) +
                         th.w1 * (tw.w0 * r1[tw.i0] + tw.w1 * r1[tw.i1]);
            }
        }
    }
}

template <class T>
void upsample_bilinear2d_bwd_cpu(const T* dy, T* dx, int64_t planes, int64_t H, int64_t W,
                                 int64_t Ho, int64_t Wo, bool align_corners) {
#pragma omp parallel for schedule(static)
    for (int64_t pl = 0; pl < planes; ++pl) {
        T* dxp = dx + pl * H * W;
        std::fill(dxp, dxp + H * W, T(0));
        for (int64_t oh = 0; oh < Ho; ++oh) {
            const Tap<T> th = tap<T>(oh, H, Ho, align_corners);
            T* r0 = dxp + th.i0 * W;
            T* r1 = dxp + th.i1 * W;
            const T* dyr = dy + (pl * Ho + oh) * Wo;
            for (int64_t ow = 0; ow < Wo; ++ow) {
                const Tap<T> tw = tap<T>(ow, W, Wo, align_corners);
                const T d0 = th.w0 * dyr[ow], d1 = th.w1 * dyr[ow];
                r0[tw.i0] += tw.w0 * d0;
                r0[tw.i1] += tw.w1 * d0;
                r1[tw.i0] += tw.w0 * d1;
                r1[tw.i1] += tw.w1 * d1;
            }
        }
    }
}

template void upsample_nearest2d_fwd_cpu<float>(const float*, float*, int64_t, int64_t, int64_t,
                                                int64_t);
template void upsample_nearest2d_fwd_cpu<double>(const double*, double*, int64_t, int64_t,
                                                 int64_t, int64_t);
template void upsample_nearest2d_bwd_cpu<float>(const float*, float*, int64_t, int64_t, int64_t,
                                                int64_t);
template void upsample_nearest2d_bwd_cpu<double>(const double*, double*, int64_t, int64_t,
                                                 int64_t, int64_t);
template void upsample_bilinear2d_fwd_cpu<float>(const float*, float*, int64_t, int64_t, int64_t,
                                                 int64_t, int64_t, bool);
template void upsample_bilinear2d_fwd_cpu<double>(const double*, double*, int64_t, int64_t,
                                                  int64_t, int64_t, int64_t, bool);
template void upsample_bilinear2d_bwd_cpu<float>(const float*, float*, int64_t, int64_t, int64_t,
                                                 int64_t, int64_t, bool);
template void upsample_bilinear2d_bwd_cpu<double>(const double*, double*, int64_t, int64_t,
                                                  int64_t, int64_t, int64_t, bool);

}  // namespace g2l::kernels
