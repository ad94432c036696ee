// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320: zlib's crc32, the one MCAP's chunk,
// data-section and summary CRCs use), for the MCAP chunks rblog writes
// (rblog/record/mcap_writer.py, _Writer: a chunk's uncompressed CRC).
//
// zlib's braided table CRC runs at ~2 GB/s here: ~24 ms of CPU per run of
// samples/spinning_bodies.toml (54 MB of chunk records), 10% of the MCAP writer's time. On CPUs with
// carry-less multiplication (PCLMULQDQ, x86-64 since 2010) the CRC folds 64 bytes per step instead
// (Gopal et al., "Fast CRC Computation for Generic Polynomials Using PCLMULQDQ Instruction",
// Intel 2009; the same folding constants as zlib-ng's and Chromium's zlib): the data, seen as a
// polynomial over GF(2), is reduced 512 bits at a time by multiplying the running remainder by
// x^(512+-64) mod P (k1, k2), then folded to 128 bits (k3, k4), to 64 (k5), and Barrett-reduced to
// 32 bits (P' and mu). Lengths below 64 and the tail after the last 16-byte block go through the
// byte table. Without PCLMULQDQ (checked at run time) everything does.
//
// The result is zlib.crc32(data, crc) to the bit (tests/record/test_crc32.py compares them on
// every length 0..300, random offsets, and whole chunks).
#include <nanobind/nanobind.h>

#include <cstdint>

#if defined(__x86_64__) || defined(_M_X64)
#include <immintrin.h>
#define RB_CRC_PCLMUL 1
#endif

#include "common/py.hpp"

namespace rb {

namespace {

using u8 = std::uint8_t;
using u32 = std::uint32_t;
using u64 = std::uint64_t;

struct ByteTable {
    u32 t[256];
    ByteTable() {
        for (u32 i = 0; i < 256; ++i) {
            u32 c = i;
            for (int k = 0; k < 8; ++k) c = (c & 1) ? (0xEDB88320u ^ (c >> 1)) : (c >> 1);
            t[i] = c;
        }
    }
};

const ByteTable& table() {
    static const ByteTable tab;
    return tab;
}

// The running CRC register (not inverted) over n bytes, one byte at a time.
u32 crc_bytes(u32 reg, const u8* p, i64 n) {
    const u32* t = table().t;
    for (i64 i = 0; i < n; ++i) reg = t[(reg ^ p[i]) & 0xFF] ^ (reg >> 8);
    return reg;
}

#ifdef RB_CRC_PCLMUL
// The register over n bytes, n >= 64 and a multiple of 16 (the folding of the paper above).
__attribute__((target("pclmul,sse4.1"))) u32 crc_fold(u32 reg, const u8* buf, i64 len) {
    alignas(16) static const u64 k1k2[] = {0x0154442bd4ull, 0x01c6e41596ull};
    alignas(16) static const u64 k3k4[] = {0x01751997d0ull, 0x00ccaa009eull};
    alignas(16) static const u64 k5k0[] = {0x0163cd6124ull, 0x0000000000ull};
    alignas(16) static const u64 poly[] = {0x01db710641ull, 0x01f7011641ull};
    __m128i x0, x1, x2, x3, x4, x5, x6, x7, x8, y5, y6, y7, y8;

    x1 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(buf + 0x00));
    x2 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(buf + 0x10));
    x3 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(buf + 0x20));
    x4 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(buf + 0x30));
    x1 = _mm_xor_si128(x1, _mm_cvtsi32_si128(static_cast<int>(reg)));
    x0 = _mm_load_si128(reinterpret_cast<const __m128i*>(k1k2));
    buf += 64;
    len -= 64;
    // fold 512 bits at a time (four lanes of 128)
    while (len >= 64) {
        x5 = _mm_clmulepi64_si128(x1, x0, 0x00);
        x6 = _mm_clmulepi64_si128(x2, x0, 0x00);
        x7 = _mm_clmulepi64_si128(x3, x0, 0x00);
        x8 = _mm_clmulepi64_si128(x4, x0, 0x00);
        x1 = _mm_clmulepi64_si128(x1, x0, 0x11);
        x2 = _mm_clmulepi64_si128(x2, x0, 0x11);
        x3 = _mm_clmulepi64_si128(x3, x0, 0x11);
        x4 = _mm_clmulepi64_si128(x4, x0, 0x11);
        y5 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(buf + 0x00));
        y6 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(buf + 0x10));
        y7 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(buf + 0x20));
        y8 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(buf + 0x30));
        x1 = _mm_xor_si128(_mm_xor_si128(x1, x5), y5);
        x2 = _mm_xor_si128(_mm_xor_si128(x2, x6), y6);
        x3 = _mm_xor_si128(_mm_xor_si128(x3, x7), y7);
        x4 = _mm_xor_si128(_mm_xor_si128(x4, x8), y8);
        buf += 64;
        len -= 64;
    }
    // the four lanes into one of 128 bits
    x0 = _mm_load_si128(reinterpret_cast<const __m128i*>(k3k4));
    x5 = _mm_clmulepi64_si128(x1, x0, 0x00);
    x1 = _mm_clmulepi64_si128(x1, x0, 0x11);
    x1 = _mm_xor_si128(_mm_xor_si128(x1, x2), x5);
    x5 = _mm_clmulepi64_si128(x1, x0, 0x00);
    x1 = _mm_clmulepi64_si128(x1, x0, 0x11);
    x1 = _mm_xor_si128(_mm_xor_si128(x1, x3), x5);
    x5 = _mm_clmulepi64_si128(x1, x0, 0x00);
    x1 = _mm_clmulepi64_si128(x1, x0, 0x11);
    x1 = _mm_xor_si128(_mm_xor_si128(x1, x4), x5);
    // 128 bits at a time
    while (len >= 16) {
        x2 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(buf));
        x5 = _mm_clmulepi64_si128(x1, x0, 0x00);
        x1 = _mm_clmulepi64_si128(x1, x0, 0x11);
        x1 = _mm_xor_si128(_mm_xor_si128(x1, x2), x5);
        buf += 16;
        len -= 16;
    }
    // 128 -> 64 bits
    x2 = _mm_clmulepi64_si128(x1, x0, 0x10);
    x3 = _mm_setr_epi32(~0, 0, ~0, 0);
    x1 = _mm_srli_si128(x1, 8);
    x1 = _mm_xor_si128(x1, x2);
    x0 = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(k5k0));
    x2 = _mm_srli_si128(x1, 4);
    x1 = _mm_and_si128(x1, x3);
    x1 = _mm_clmulepi64_si128(x1, x0, 0x00);
    x1 = _mm_xor_si128(x1, x2);
    // Barrett reduction to 32 bits
    x0 = _mm_load_si128(reinterpret_cast<const __m128i*>(poly));
    x2 = _mm_and_si128(x1, x3);
    x2 = _mm_clmulepi64_si128(x2, x0, 0x10);
    x2 = _mm_and_si128(x2, x3);
    x2 = _mm_clmulepi64_si128(x2, x0, 0x00);
    x1 = _mm_xor_si128(x1, x2);
    return static_cast<u32>(_mm_extract_epi32(x1, 1));
}

bool has_pclmul() {
    static const bool ok = __builtin_cpu_supports("pclmul") && __builtin_cpu_supports("sse4.1");
    return ok;
}
#endif

}  // namespace

// zlib.crc32(data[:n], crc): the CRC of n more bytes after a CRC of `crc`.
u32 crc32_ieee(u32 crc, const u8* p, i64 n) {
    u32 reg = ~crc;
#ifdef RB_CRC_PCLMUL
    if (n >= 64 && has_pclmul()) {
        const i64 body = n & ~static_cast<i64>(15);
        reg = crc_fold(reg, p, body);
        p += body;
        n -= body;
    }
#endif
    return ~crc_bytes(reg, p, n);
}

void bind_crc32(nanobind::module_& m) {
    namespace nb = nanobind;
    m.def(
        "crc32",
        [](nb::handle data_, std::uint32_t crc) {
            // read-only buffers too (bytes, a chunk's memoryview): the CRC only reads
            nb::ndarray<const u8, nb::ndim<1>, nb::c_contig, nb::device::cpu> data;
            if (!nb::try_cast(data_, data, false))
                throw nb::type_error("crc32: data: expected a C-contiguous 1-D uint8 array");
            const u8* p = data.data();
            const i64 n = static_cast<i64>(data.shape(0));
            u32 out;
            {
                nb::gil_scoped_release release;
                out = crc32_ieee(crc, p, n);
            }
            return out;
        },
        nb::arg("data"), nb::arg("crc") = 0,
        "zlib.crc32(data, crc) of a uint8 array (carry-less multiplication where the CPU has "
        "it). Releases the GIL.");
}

}  // namespace rb
