// The one place that knows about GPU compilers. Everything else writes LBL_HOSTDEV.
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
