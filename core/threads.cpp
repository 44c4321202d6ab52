// SPDX-License-Identifier: MIT
#include "core/threads.h"

#include "core/error.h"
#ifdef G2L_WITH_OPENMP
#include <omp.h>
#endif

namespace g2l {

int num_threads() {
#ifdef G2L_WITH_OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

void set_num_threads(int n) {
    // Checked in both builds so a bad thread count fails the same way with and without OpenMP.
    G2L_CHECK(n >= 1, "set_num_threads: n must be >= 1, got ", n);
#ifdef G2L_WITH_OPENMP
    omp_set_num_threads(n);
#endif
}

}  // namespace g2l
