// The one place that knows about GPU compilers. Everything else writes LBL_HOSTDEV,
// LBL_FORCEINLINE and LBL_UNROLL.
#pragma once

#if defined(__CUDACC__) || defined(__HIPCC__)
#define LBL_HOSTDEV __host__ __device__
#define LBL_GPU_COMPILER 1
#else
#define LBL_HOSTDEV
#define LBL_GPU_COMPILER 0
#endif

#if LBL_GPU_COMPILER
#define LBL_FORCEINLINE __forceinline__
#elif defined(_MSC_VER)
#define LBL_FORCEINLINE __forceinline
#else
#define LBL_FORCEINLINE inline __attribute__((always_inline))
#endif

// Full unrolling of the 19-direction loops (the values then stay in registers on a GPU, and GCC
// keeps the SIMD loop around them).
#if LBL_GPU_COMPILER || defined(__clang__)
#define LBL_UNROLL _Pragma("unroll")
#elif defined(__GNUC__)
#define LBL_UNROLL _Pragma("GCC unroll 19")
#else
#define LBL_UNROLL
#endif
