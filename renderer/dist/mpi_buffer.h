// A buffer for non-blocking MPI operations that outlives a wait which throws. Header-only,
// without MPI, so that it is tested with the core.
#pragma once

#include <exception>
#include <utility>

namespace kdt::dist {

/// The buffer of a non-blocking MPI operation: freed at the end of its scope on a normal
/// return, but kept (never freed) when an exception unwinds the scope, since a wait that
/// throws (FarmTimeout, FarmInterrupted) leaves the operation pending, MPI may still read or
/// write the buffer until the process ends (without MPI_Finalize after those), and memory
/// freed meanwhile could be reused.
template <typename T>
class MpiBuffer {
public:
    template <typename... Args>
    explicit MpiBuffer(Args&&... args)
        : p_(new T(std::forward<Args>(args)...)), unwinding_(std::uncaught_exceptions()) {}
    MpiBuffer(const MpiBuffer&) = delete;
    MpiBuffer& operator=(const MpiBuffer&) = delete;
    ~MpiBuffer() {
        if (std::uncaught_exceptions() == unwinding_) delete p_;
    }
    T& operator*() const { return *p_; }
    T* operator->() const { return p_; }

private:
    T* p_;
    int unwinding_;  // exceptions in flight when made: more at the end means unwinding
};

}  // namespace kdt::dist
