// The CPU sweep's SIMD and floating-point helpers (backends/openmp): non-temporal line stores,
// float16 conversions by chunk, and a scoped flush-to-zero mode. Header-only, used by the sweep
// (cpu_lattice_solver.h) and by the backend's planning questions (kHasFloat16).
#pragma once

#include <cstring>
#include <type_traits>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#include <pmmintrin.h>
#include <xmmintrin.h>
#define LBL_X86 1
#else
#define LBL_X86 0
#endif

#define LBL_INLINE_LAMBDA __attribute__((always_inline))

namespace lblight::openmp {

// float16 storage needs the compiler's _Float16 (GCC 12 and Clang on x86-64; conversions in one
// instruction with F16C, which -march=native enables where the CPU has it).
#if defined(__FLT16_MANT_DIG__)
#define LBLIGHT_CPU_FLOAT16 1
inline constexpr bool kHasFloat16 = true;
#else
inline constexpr bool kHasFloat16 = false;
#endif

// One cache line from an aligned buffer to aligned memory, bypassing the caches.
template <typename Real>
inline void stream_line(Real* dst, const Real* src) {
#if LBL_X86 && defined(__AVX512F__)
  if constexpr (sizeof(Real) == 4) _mm512_stream_ps(reinterpret_cast<float*>(dst), _mm512_load_ps(reinterpret_cast<const float*>(src)));
  else _mm512_stream_pd(reinterpret_cast<double*>(dst), _mm512_load_pd(reinterpret_cast<const double*>(src)));
#elif LBL_X86 && defined(__AVX__)
  for (int h = 0; h < 2; ++h) {
    if constexpr (sizeof(Real) == 4)
      _mm256_stream_ps(reinterpret_cast<float*>(dst) + 8 * h, _mm256_load_ps(reinterpret_cast<const float*>(src) + 8 * h));
    else
      _mm256_stream_pd(reinterpret_cast<double*>(dst) + 4 * h, _mm256_load_pd(reinterpret_cast<const double*>(src) + 4 * h));
  }
#elif LBL_X86
  for (int q = 0; q < 4; ++q) {
    if constexpr (sizeof(Real) == 4)
      _mm_stream_ps(reinterpret_cast<float*>(dst) + 4 * q, _mm_load_ps(reinterpret_cast<const float*>(src) + 4 * q));
    else
      _mm_stream_pd(reinterpret_cast<double*>(dst) + 2 * q, _mm_load_pd(reinterpret_cast<const double*>(src) + 2 * q));
  }
#else
  std::memcpy(dst, src, 64);
#endif
}

// Flush-to-zero and denormals-are-zero for the calling thread while in scope, then the
// thread's previous MXCSR modes again, so a library caller's floating-point mode is never changed.
// Light decaying through thick media reaches subnormal values (< 1.2e-38 in float32), which
// would otherwise take a slow path per operation; values that small are 0 for any renderer.
class ScopedFlushDenormals {
 public:
  explicit ScopedFlushDenormals(bool on) {
#if defined(__SSE2__)
    if (on) {
      saved_ = _mm_getcsr();
      active_ = true;
      _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
      _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
    }
#else
    (void)on;
#endif
  }
  ~ScopedFlushDenormals() {
#if defined(__SSE2__)
    // the previous control bits; the sticky exception flags (bits 0-5) keep what was raised
    if (active_) _mm_setcsr((saved_ & ~0x3Fu) | ((saved_ | _mm_getcsr()) & 0x3Fu));
#endif
  }
  ScopedFlushDenormals(const ScopedFlushDenormals&) = delete;
  ScopedFlushDenormals& operator=(const ScopedFlushDenormals&) = delete;

 private:
  unsigned saved_ = 0;
  bool active_ = false;
};

inline void stream_fence() {
#if LBL_X86
  _mm_sfence();
#endif
}

// N 16-bit floats (any alignment) to Real and back (any alignment: a row's shifted last chunk), rounding to
// nearest even as the GPU's __float2half_rn does. With AVX-512 or F16C one instruction converts
// 16 or 8 values; GCC 12 does not vectorise _Float16 conversions itself. Real = Store needs none.
template <int N, typename Real, typename Half>
inline void halves_to_reals(const Half* in, Real* out) {
#if LBL_X86 && defined(__AVX512F__)
  if constexpr (std::is_same_v<Real, float> && N % 16 == 0 && sizeof(Half) == 2) {
    for (int i = 0; i < N; i += 16)
      _mm512_store_ps(out + i, _mm512_mask_cvtph_ps(_mm512_setzero_ps(), 0xFFFF,  // masked: GCC 12 warns
                                                   _mm256_loadu_si256(reinterpret_cast<const __m256i*>(in + i))));  // on the plain one
    return;
  }
#elif LBL_X86 && defined(__F16C__)
  if constexpr (std::is_same_v<Real, float> && N % 8 == 0 && sizeof(Half) == 2) {
    for (int i = 0; i < N; i += 8)
      _mm256_store_ps(out + i, _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(in + i))));
    return;
  }
#endif
  for (int i = 0; i < N; ++i) out[i] = static_cast<Real>(in[i]);
}
template <int N, typename Real, typename Half>
inline void reals_to_halves(const Real* in, Half* out) {
#if LBL_X86 && defined(__AVX512F__)
  if constexpr (std::is_same_v<Real, float> && N % 16 == 0 && sizeof(Half) == 2) {
    for (int i = 0; i < N; i += 16)
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + i),
                          _mm512_mask_cvtps_ph(_mm256_setzero_si256(), 0xFFFF, _mm512_load_ps(in + i),
                                              _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC));
    return;
  }
#elif LBL_X86 && defined(__F16C__)
  if constexpr (std::is_same_v<Real, float> && N % 8 == 0 && sizeof(Half) == 2) {
    for (int i = 0; i < N; i += 8)
      _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i),
                       _mm256_cvtps_ph(_mm256_load_ps(in + i), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC));
    return;
  }
#endif
  for (int i = 0; i < N; ++i) out[i] = static_cast<Half>(in[i]);
}

}  // namespace lblight::openmp
