// MpiBuffer (renderer/dist/mpi_buffer.h): freed on a normal return, kept while an exception
// unwinds its scope (a wait that threw leaves its MPI operation pending on the buffer).
#include "renderer/dist/mpi_buffer.h"

#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

namespace kdt::dist {
namespace {

struct Counted {
    static inline int destroyed = 0;
    std::vector<int> data;
    explicit Counted(size_t n) : data(n, 7) {}
    ~Counted() { ++destroyed; }
};

TEST(MpiBuffer, FreedOnReturnKeptWhileUnwinding) {
    Counted::destroyed = 0;
    {
        MpiBuffer<Counted> b(size_t(4));
        EXPECT_EQ(b->data.size(), 4u);
        EXPECT_EQ((*b).data[3], 7);
    }
    EXPECT_EQ(Counted::destroyed, 1);

    Counted* kept = nullptr;
    try {
        MpiBuffer<Counted> b(size_t(4));
        kept = &*b;
        throw std::runtime_error("a wait timed out");
    } catch (const std::runtime_error&) {
    }
    EXPECT_EQ(Counted::destroyed, 1);  // still there for the pending operation
    ASSERT_NE(kept, nullptr);
    EXPECT_EQ(kept->data[0], 7);
    delete kept;  // the test's own cleanup, so that LeakSanitizer stays quiet

    // Made while an exception is in flight (in a handler), it is freed at the end of its
    // scope as usual.
    Counted::destroyed = 0;
    try {
        throw std::runtime_error("outer");
    } catch (const std::runtime_error&) {
        MpiBuffer<Counted> b(size_t(1));
    }
    EXPECT_EQ(Counted::destroyed, 1);
}

}  // namespace
}  // namespace kdt::dist
