// The error plumbing of libwarpray_cuda's C functions (pdacrt.cu, cis.cu): a function
// body runs inside `guarded`, which turns an exception into a non-zero return and keeps
// its message for the library's `*_last_error()`.
#pragma once

#include <exception>
#include <string>

namespace wr {

/// A failed CUDA call, with what was being done.
struct CudaError {
    std::string what;
};

template <class F>
int guarded(std::string& last_error, F f) {
    try {
        f();
        return 0;
    } catch (const CudaError& e) {
        last_error = e.what;
    } catch (const std::exception& e) {
        last_error = e.what();
    }
    return 1;
}

}  // namespace wr
