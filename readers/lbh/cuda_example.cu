// lbh_reader.h in CUDA (or HIP) device code: one thread per sample, the stream copied to device
// memory once, the lattice and a relighter passed by value. Compile check:
//   nvcc -std=c++17 -arch=sm_90 -I readers/lbh -c readers/lbh/cuda_example.cu
//   hipcc -std=c++17 --offload-arch=gfx90a -I readers/lbh -c -x hip readers/lbh/cuda_example.cu
#if defined(__HIPCC__)
#include <hip/hip_runtime.h>
// The few runtime calls this example makes, under their HIP names.
#define cudaError_t hipError_t
#define cudaSuccess hipSuccess
#define cudaMalloc hipMalloc
#define cudaMemcpy hipMemcpy
#define cudaFree hipFree
#define cudaGetErrorString hipGetErrorString
#define cudaMemcpyHostToDevice hipMemcpyHostToDevice
#define cudaMemcpyDeviceToHost hipMemcpyDeviceToHost
#else
#include <cuda_runtime.h>
#endif

#include <cmath>
#include <cstdio>
#include <vector>

#include "lbh_reader.h"

__global__ void relight_kernel(lbh::Lattice lattice, lbh::Relighter relighter, const float3* world_pos, float3* out,
                               int count) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= count) return;
  const float3 p = world_pos[i];
  const lbh::Rgb v = lbh::relight_world(lattice, relighter, p.x, p.y, p.z);
  out[i] = make_float3(v.r, v.g, v.b);
}

__global__ void sample_kernel(lbh::Lattice lattice, lbh::SolutionView view, const float3* index_pos, float3* out,
                              int count) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= count) return;
  const float3 p = index_pos[i];
  const lbh::Rgb v = lbh::sample_index(lattice, view, p.x, p.y, p.z);
  out[i] = make_float3(v.r, v.g, v.b);
}

static bool ok(cudaError_t e, const char* what) {
  if (e != cudaSuccess) std::fprintf(stderr, "%s: %s\n", what, cudaGetErrorString(e));
  return e == cudaSuccess;
}

// Host side: validate on the host, copy the bytes, rebase the views onto the device copy.
int main(int argc, char** argv) {
  if (argc < 2) return 2;
  lbh::Stream s;
  if (s.open_file(argv[1]) != lbh::Status::Ok) {
    std::fprintf(stderr, "%s\n", s.error().c_str());
    return 1;
  }
  void* dev = nullptr;
  if (!ok(cudaMalloc(&dev, s.size()), "no usable GPU")) return 1;  // 256-byte aligned
  if (!ok(cudaMemcpy(dev, s.data(), s.size(), cudaMemcpyHostToDevice), "copying the stream")) return 1;
  const lbh::Lattice L = s.lattice();
  const int n = 1 << 20;
  std::vector<float3> pos(n);
  for (int i = 0; i < n; ++i)
    pos[i] = make_float3(L.index_min[0] + (i % 97) * (L.n[0] - 1) / 96.0f, L.index_min[1] + (i / 97 % 89) * (L.n[1] - 1) / 88.0f,
                         L.index_min[2] + (i % 83) * (L.n[2] - 1) / 82.0f);
  float3 *dpos = nullptr, *dout = nullptr;
  if (!ok(cudaMalloc(&dpos, n * sizeof(float3)), "allocating positions") ||
      !ok(cudaMalloc(&dout, n * sizeof(float3)), "allocating results") ||
      !ok(cudaMemcpy(dpos, pos.data(), n * sizeof(float3), cudaMemcpyHostToDevice), "copying positions"))
    return 1;
  sample_kernel<<<(n + 255) / 256, 256>>>(L, s.view(0, dev), dpos, dout, n);
  std::vector<float3> out(n);
  if (!ok(cudaMemcpy(out.data(), dout, n * sizeof(float3), cudaMemcpyDeviceToHost), "sampling")) return 1;
  int bad = 0;
  for (int i = 0; i < n; i += 997) {
    const lbh::Rgb h = s.sample_index(0, pos[i].x, pos[i].y, pos[i].z);
    bad += std::fabs(h.g - out[i].y) > 1e-4f * (1 + std::fabs(h.g));
  }
  lbh::Relighter r;
  if (s.make_relighter(0.3, 0.2, -1.0, 1.0f, 0.2f, r, dev) == lbh::Status::Ok)
    relight_kernel<<<(n + 255) / 256, 256>>>(L, r, dpos, dout, n);
  std::printf("%s: device samples %s host samples\n", argv[1], bad ? "DIFFER from" : "match");
  for (void* p : {dev, static_cast<void*>(dpos), static_cast<void*>(dout)}) (void)cudaFree(p);
  return bad ? 1 : 0;
}
