// SPDX-License-Identifier: MIT
#include "nn/ops/dropout.h"

#include "kernels/dropout.h"
#include "nn/data_parallel.h"
#include "nn/ops/dim_utils.h"
#include "nn/ops/elementwise.h"
#include "nn/ops/shape.h"

namespace g2l::nn {

Tensor dropout(const Tensor& x, double p, bool training, Rng& rng) {
    detail::check_float_input("dropout", "x", x);
    G2L_CHECK(p >= 0 && p < 1, "dropout: probability p must be in [0, 1), got ", p);
    // Inverted dropout scales at training time, so eval mode is the identity: x itself, no node.
    if (!training || p == 0) return x;
    // The mask holds 0 or 1 / (1 - p), drawn on the host in a fixed stream order, then moved to
    // x's device. The product with x (a differentiable mul with a constant) gives dy * mask.
    // Data-parallel training (nn/data_parallel.h): the mask of the global batch, drawn in the
    // same stream order as one process would, and this process's rows of it.
    const DataParallel* dp = data_parallel();
    if (dp && x.dim() >= 1 && dp->global_batch > x.size(0)) {
        G2L_CHECK(dp->batch_offset >= 0 && dp->batch_offset + x.size(0) <= dp->global_batch,
                  "dropout: rows [", dp->batch_offset, ", ", dp->batch_offset + x.size(0),
                  ") of x ", x.desc(), " are outside the global batch of ", dp->global_batch);
        Shape gshape = x.shape();
        gshape[0] = dp->global_batch;
        Tensor full = Tensor::empty(gshape, x.dtype());  // host: the Rng stream lives here
        kernels::dropout_mask(full, p, rng);
        const Tensor mask = slice(full, 0, dp->batch_offset, dp->batch_offset + x.size(0));
        return mul(x, mask.to(x.device()));
    }
    Tensor mask = Tensor::empty(x.shape(), x.dtype());  // host: the Rng stream lives here
    kernels::dropout_mask(mask, p, rng);
    return mul(x, mask.to(x.device()));
}

}  // namespace g2l::nn
