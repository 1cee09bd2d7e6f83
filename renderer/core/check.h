// Programmer-error checks: KDT_CHECK is always on, KDT_DCHECK only in debug builds.
// Bad input is never checked with these; io throws kdt::Error for that.
#pragma once

#include <cstdio>
#include <cstdlib>

#define KDT_CHECK(cond)                                                                   \
    do {                                                                                  \
        if (!(cond)) {                                                                    \
            std::fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond); \
            std::abort();                                                                 \
        }                                                                                 \
    } while (0)

#ifdef NDEBUG
#define KDT_DCHECK(cond) \
    do {                 \
    } while (0)
#else
#define KDT_DCHECK(cond) KDT_CHECK(cond)
#endif
