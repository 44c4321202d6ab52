// SPDX-License-Identifier: MIT
// Layout copies: the dispatch points (kernels/dispatch.h); CPU kernels in shape_cpu.cpp.
#include "kernels/shape.h"

#include "kernels/dispatch.h"

namespace g2l::kernels {

void copy_slab(const Tensor& src, int64_t src_D, int64_t src_off, Tensor& dst, int64_t dst_D,
               int64_t dst_off, int64_t outer, int64_t len, int64_t inner) {
    // Layout copies also move i32 tensors (indices, labels); only the gradient kernel below is
    // float-only.
    dispatch<Types::FloatOrI32>(
        "copy_slab", {&src, &dst},
        [&](auto tag) {
            using T = decltype(tag);
            copy_slab_cpu<T>(src.data<T>(), src_D, src_off, dst.data<T>(), dst_D, dst_off, outer,
                             len, inner);
        });
}

void permute(const Tensor& x, const std::vector<int64_t>& perm, Tensor& y) {
    dispatch<Types::FloatOrI32>(
        "permute", {&x, &y},
        [&](auto tag) {
            using T = decltype(tag);
            permute_cpu<T>(x.data<T>(), x.shape(), perm, y.data<T>());
        });
}

void index_select_fwd(const Tensor& x, const Tensor& idx, Tensor& y, int64_t outer, int64_t D,
                       int64_t inner) {
    dispatch<Types::FloatOrI32>(
        "index_select", {&x, &idx, &y},
        [&](auto tag) {
            using T = decltype(tag);
            index_select_fwd_cpu<T>(x.data<T>(), idx.data<int32_t>(), idx.numel(), y.data<T>(),
                                    outer, D, inner);
        });
}

void index_select_bwd(const Tensor& dy, const Tensor& idx, Tensor& dx, int64_t outer, int64_t D,
                      int64_t inner) {
    dispatch("index_select backward", {&dy, &idx, &dx}, [&](auto tag) {
        using T = decltype(tag);
        index_select_bwd_cpu<T>(dy.data<T>(), idx.data<int32_t>(), idx.numel(), dx.data<T>(),
                                outer, D, inner);
    });
}

}  // namespace g2l::kernels
