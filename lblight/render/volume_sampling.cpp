#include "lblight/render/volume_sampling.h"

#include <omp.h>

#include <atomic>
#include <exception>

namespace lblight::render_detail {

void for_each_row(int height, int threads, const std::function<void(double)>& progress, const RunContext& ctx,
                  const std::function<void(int)>& row) {
  std::atomic<int> rows{0};
  const int n = threads > 0 ? threads : std::max(1, omp_get_max_threads());
  std::exception_ptr failure;
#pragma omp parallel for schedule(dynamic, 1) num_threads(n)
  for (int py = 0; py < height; ++py) {
    try {
      ctx.check_cancelled();
      row(py);
    } catch (...) {
#pragma omp critical(lblight_render)
      if (!failure) failure = std::current_exception();
    }
    const int done = ++rows;
    if (progress && omp_get_thread_num() == 0) progress(static_cast<double>(done) / height);
  }
  if (failure) std::rethrow_exception(failure);
  ctx.check_cancelled();
}


}  // namespace lblight::render_detail
