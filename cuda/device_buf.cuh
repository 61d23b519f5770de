// Device memory for the CUDA twins (cuda/pdacrt.cu, cuda/bvh.cu): a checked CUDA call
// and a growable device array.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <string>
#include <utility>

#include "guarded.h"

namespace wr {

inline void check(cudaError_t e, const char* what) {
    if (e != cudaSuccess) throw CudaError{std::string(what) + ": " + cudaGetErrorString(e)};
}

/// A device array that keeps its allocation when it shrinks (`DeviceBuffer::resize`).
/// Growing does not keep the contents: every caller overwrites what it resized.
template <class T>
struct Buf {
    T* p = nullptr;
    size_t n = 0, cap = 0;
    size_t* live = nullptr;
    void resize(size_t m) {
        if (m > cap) {
            if (p) check(cudaFree(p), "cudaFree");
            size_t c = m + m / 4 + 16;
            check(cudaMalloc(&p, c * sizeof(T)), "cudaMalloc");
            if (live) *live += (c - cap) * sizeof(T);
            cap = c;
        }
        n = m;
    }
    ~Buf() {
        if (p) cudaFree(p);
    }
    void swap(Buf& o) {
        std::swap(p, o.p);
        std::swap(n, o.n);
        std::swap(cap, o.cap);
    }
};

}  // namespace wr
