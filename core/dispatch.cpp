// SPDX-License-Identifier: MIT
#include "core/dispatch.h"

namespace g2l {

void require_same(const char* op, std::initializer_list<const Tensor*> ts) {
    const Tensor* first = nullptr;
    for (const Tensor* t : ts) {
        // Optional inputs (e.g. linear's bias) arrive undefined and take no part in the check.
        if (!t || !t->defined()) continue;
        if (!first) { first = t; continue; }
        G2L_CHECK(t->dtype() == first->dtype() && t->device() == first->device(), op,
                  ": tensors must share dtype and device, got ", first->desc(), " and ",
                  t->desc());
    }
}

void require_rank(const char* op, const char* name, const Tensor& t, int64_t rank,
                  const char* layout) {
    G2L_CHECK(t.defined(), op, ": ", name, " is undefined");
    G2L_CHECK(t.dim() == rank, op, ": expected ", name, " as ", layout, ", got ", t.desc());
}

}  // namespace g2l
