// The x86 SIMD intrinsics the PLY decoders and the OBJ line scan use, where the target has
// SSE2 at least.
// Internal to renderer/io.
#pragma once

#if defined(__SSE2__)
// GCC 12 warns about the deliberately undefined vectors inside its own AVX-512 intrinsics
// (GCC PR 105593); the pragma covers the header's lines only.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <immintrin.h>
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif
