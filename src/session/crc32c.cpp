#include "session/crc32c.hpp"

#include <array>
#include <cstring>

#if defined(__x86_64__)
#include <cpuid.h>
#include <immintrin.h>
#include <nmmintrin.h>
#elif defined(__aarch64__) && defined(__ARM_FEATURE_CRC32)
#include <arm_acle.h>
#endif

#include "wiretape/session.hpp"

namespace wiretape {

namespace {

// Slicing-by-8 tables of the reflected Castagnoli polynomial.
using CrcTables = std::array<std::array<std::uint32_t, 256>, 8>;

CrcTables make_crc_tables() {
  CrcTables tables{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t crc = i;
    for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ (0x82F63B78u & (0u - (crc & 1u)));
    tables[0][i] = crc;
  }
  for (std::size_t i = 0; i < 256; ++i) {
    for (std::size_t slice = 1; slice < 8; ++slice) {
      const std::uint32_t previous = tables[slice - 1][i];
      tables[slice][i] = (previous >> 8) ^ tables[0][previous & 0xFF];
    }
  }
  return tables;
}

const CrcTables& crc_tables() {
  static const CrcTables tables = make_crc_tables();
  return tables;
}

}  // namespace

namespace {

// The hardware paths run three independent streams over consecutive blocks
// (the crc32 instruction's latency is three times its issue interval) and
// join them by advancing a stream's register over the blocks that follow it.
// Each join costs about as much as 64 bytes of streaming, so a buffer takes
// the longest blocks it holds three of: a recorded read of a pty (4095 bytes)
// is one round of the middle length, one of the short, and a 255-byte tail.
constexpr std::size_t crc_long_block = 8192;
constexpr std::size_t crc_middle_block = 1024;
constexpr std::size_t crc_short_block = 256;
// Each stream takes this many bytes a loop step: four crc32 instructions
// per loop test.
constexpr std::size_t crc_stride = 32;
static_assert(crc_long_block % crc_stride == 0 && crc_middle_block % crc_stride == 0 &&
                  crc_short_block % crc_stride == 0,
              "the streams advance a stride a step");

// Advancing a raw CRC register over n zero bytes is linear over GF(2): one
// table per byte of the register.
using CrcShiftTable = std::array<std::array<std::uint32_t, 256>, 4>;

CrcShiftTable make_crc_shift_table(std::size_t zero_bytes) {
  // zero_bytes is a multiple of 8: eight zero bytes at a time by the
  // slicing tables (the data bytes' lookups are all t[k][0] == 0).
  const CrcTables& t = crc_tables();
  std::array<std::uint32_t, 32> basis{};
  for (std::size_t bit = 0; bit < 32; ++bit) {
    std::uint32_t crc = 1u << bit;
    for (std::size_t i = 0; i < zero_bytes; i += 8) {
      crc = t[7][crc & 0xFF] ^ t[6][(crc >> 8) & 0xFF] ^ t[5][(crc >> 16) & 0xFF] ^
            t[4][crc >> 24];
    }
    basis[bit] = crc;
  }
  CrcShiftTable table{};
  for (std::size_t byte = 0; byte < 4; ++byte) {
    for (std::uint32_t value = 0; value < 256; ++value) {
      std::uint32_t shifted = 0;
      for (std::size_t bit = 0; bit < 8; ++bit) {
        if ((value >> bit) & 1u) shifted ^= basis[byte * 8 + bit];
      }
      table[byte][value] = shifted;
    }
  }
  return table;
}

inline std::uint32_t crc_shift(const CrcShiftTable& table, std::uint32_t crc) {
  return table[0][crc & 0xFF] ^ table[1][(crc >> 8) & 0xFF] ^ table[2][(crc >> 16) & 0xFF] ^
         table[3][crc >> 24];
}

const CrcShiftTable& crc_long_shift() {
  static const CrcShiftTable table = make_crc_shift_table(crc_long_block);
  return table;
}
const CrcShiftTable& crc_middle_shift() {
  static const CrcShiftTable table = make_crc_shift_table(crc_middle_block);
  return table;
}
const CrcShiftTable& crc_short_shift() {
  static const CrcShiftTable table = make_crc_shift_table(crc_short_block);
  return table;
}

inline std::uint64_t load_u64(const unsigned char* p) {
  std::uint64_t value;
  std::memcpy(&value, p, sizeof value);
  return value;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define WIRETAPE_CRC32C_HARDWARE 1

// Newer clang splits the CRC32 instruction out of SSE 4.2 as feature "crc32";
// gcc accepts the name too, so both are named wherever the instruction is used.
#define WIRETAPE_CRC32C_TARGET __attribute__((target("sse4.2,crc32")))

// The register is kept 64 bits wide between steps, as the instruction
// writes it (upper half zero): a 32-bit one costs a zero-extending move a step.
using CrcRegister = std::uint64_t;

WIRETAPE_CRC32C_TARGET inline CrcRegister crc_step(CrcRegister crc, const unsigned char* p) {
  return _mm_crc32_u64(crc, load_u64(p));
}
WIRETAPE_CRC32C_TARGET inline CrcRegister crc_step_byte(CrcRegister crc, unsigned char byte) {
  return _mm_crc32_u8(static_cast<std::uint32_t>(crc), byte);
}

// CPUID read directly, not __builtin_cpu_supports: that needs the compiler
// runtime's __cpu_model, which some toolchains (zig's, for the
// manylinux_2_28 wheel) do not provide or do not initialise.
struct CpuFeatures {
  bool sse42 = false;
  bool pclmul = false;
  bool avx512_folding = false;  // AVX-512 F and VL, VPCLMULQDQ, and the OS saves ZMM state
};

CpuFeatures read_cpu_features() {
  CpuFeatures features;
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  if (__get_cpuid(1, &eax, &ebx, &ecx, &edx) == 0) return features;
  features.sse42 = (ecx & bit_SSE4_2) != 0;
  features.pclmul = (ecx & bit_PCLMUL) != 0;
  const bool os_saves_state = (ecx & bit_OSXSAVE) != 0;
  unsigned leaf7_ebx = 0, leaf7_ecx = 0;
  if (__get_cpuid_count(7, 0, &eax, &leaf7_ebx, &leaf7_ecx, &edx) == 0 || !os_saves_state) {
    return features;
  }
  unsigned xcr0_low = 0, xcr0_high = 0;
  __asm__("xgetbv" : "=a"(xcr0_low), "=d"(xcr0_high) : "c"(0));
  constexpr unsigned zmm_state = 0xE6;  // SSE, AVX, opmask, ZMM_Hi256, Hi16_ZMM
  features.avx512_folding = (xcr0_low & zmm_state) == zmm_state &&
                            (leaf7_ebx & bit_AVX512F) != 0 &&
                            (leaf7_ebx & bit_AVX512VL) != 0 &&
                            (leaf7_ecx & bit_VPCLMULQDQ) != 0;
  return features;
}

const CpuFeatures& cpu_features() {
  static const CpuFeatures features = read_cpu_features();
  return features;
}

bool cpu_has_crc32c() { return cpu_features().sse42; }

#elif defined(__aarch64__) && defined(__ARM_FEATURE_CRC32)
#define WIRETAPE_CRC32C_HARDWARE 1

using CrcRegister = std::uint32_t;

inline CrcRegister crc_step(CrcRegister crc, const unsigned char* p) {
  return __crc32cd(crc, load_u64(p));
}
inline CrcRegister crc_step_byte(CrcRegister crc, unsigned char byte) {
  return __crc32cb(crc, byte);
}
#define WIRETAPE_CRC32C_TARGET

bool cpu_has_crc32c() { return true; }
#endif

#ifdef WIRETAPE_CRC32C_HARDWARE
// Four steps of one stream, from p.
WIRETAPE_CRC32C_TARGET inline CrcRegister crc_stride_steps(CrcRegister crc,
                                                           const unsigned char* p) {
  crc = crc_step(crc, p);
  crc = crc_step(crc, p + 8);
  crc = crc_step(crc, p + 16);
  return crc_step(crc, p + 24);
}

inline CrcRegister crc_join(const CrcShiftTable& shift, CrcRegister crc, CrcRegister next) {
  return crc_shift(shift, static_cast<std::uint32_t>(crc)) ^ next;
}

// Three streams over [p, p + 3 * block), joined into `crc`.
template <std::size_t block>
WIRETAPE_CRC32C_TARGET inline CrcRegister crc_three_blocks(CrcRegister crc,
                                                           const unsigned char* p,
                                                           const CrcShiftTable& shift) {
  CrcRegister crc1 = 0;
  CrcRegister crc2 = 0;
  for (std::size_t i = 0; i < block; i += crc_stride) {
    crc = crc_stride_steps(crc, p + i);
    crc1 = crc_stride_steps(crc1, p + block + i);
    crc2 = crc_stride_steps(crc2, p + 2 * block + i);
  }
  return crc_join(shift, crc_join(shift, crc, crc1), crc2);
}

WIRETAPE_CRC32C_TARGET std::uint32_t crc32c_instructions(const void* data, std::size_t size,
                                                         std::uint32_t initial) {
  const auto* p = static_cast<const unsigned char*>(data);
  CrcRegister crc = ~initial;
  while (size >= 3 * crc_long_block) {
    crc = crc_three_blocks<crc_long_block>(crc, p, crc_long_shift());
    p += 3 * crc_long_block;
    size -= 3 * crc_long_block;
  }
  while (size >= 3 * crc_middle_block) {
    crc = crc_three_blocks<crc_middle_block>(crc, p, crc_middle_shift());
    p += 3 * crc_middle_block;
    size -= 3 * crc_middle_block;
  }
  while (size >= 3 * crc_short_block) {
    crc = crc_three_blocks<crc_short_block>(crc, p, crc_short_shift());
    p += 3 * crc_short_block;
    size -= 3 * crc_short_block;
  }
  while (size >= crc_stride) {
    crc = crc_stride_steps(crc, p);
    p += crc_stride;
    size -= crc_stride;
  }
  while (size >= 8) {
    crc = crc_step(crc, p);
    p += 8;
    size -= 8;
  }
  while (size-- > 0) crc = crc_step_byte(crc, *p++);
  return ~static_cast<std::uint32_t>(crc);
}
#endif

#if defined(WIRETAPE_CRC32C_HARDWARE) && defined(__x86_64__)
#define WIRETAPE_CRC32C_FOLDING 1
// Long buffers by carry-less multiplication (VPCLMULQDQ on 512-bit
// registers), about twice the three crc32 streams' speed on CPUs that have
// it: the replay checks every byte it serves (docs/benchmarks.md).
//
// A 16-byte block A·x^64 + B (A its first eight bytes) that has d more bytes
// after it contributes A·x^(8d+64) + B·x^(8d) to the CRC, and each power is
// congruent to a constant below degree 32 modulo the polynomial. Blocks are
// therefore folded forward by multiplying their halves by those constants
// and adding the product into the block d bytes ahead, until one block is
// left; the crc32 instruction reduces it. On bit-reflected operands
// PCLMULQDQ's product comes out one bit off (an extra factor of x), so the
// constants are one power lower.

// x^n mod P, P the Castagnoli polynomial, as a bit-reflected 64-bit lane.
std::uint64_t crc_fold_constant(std::size_t n) {
  std::uint32_t remainder = 1;  // not reflected: bit j is x^j
  for (std::size_t i = 0; i < n; ++i) {
    remainder = (remainder << 1) ^ ((remainder & 0x80000000u) ? 0x1EDC6F41u : 0u);
  }
  std::uint64_t lane = 0;
  for (std::size_t j = 0; j < 32; ++j) {
    if ((remainder >> j) & 1u) lane |= std::uint64_t{1} << (63 - j);
  }
  return lane;
}

// The constants that fold a block forward by `bytes`: the low lane multiplies
// the block's first eight bytes, the high lane its last eight.
struct CrcFoldConstants {
  std::uint64_t first_half;
  std::uint64_t second_half;
};
CrcFoldConstants crc_fold_constants(std::size_t bytes) {
  return {crc_fold_constant(8 * bytes + 63), crc_fold_constant(8 * bytes - 1)};
}

struct CrcFoldTable {
  CrcFoldConstants by_256 = crc_fold_constants(256);
  CrcFoldConstants by_64 = crc_fold_constants(64);
  CrcFoldConstants by_16 = crc_fold_constants(16);
};
const CrcFoldTable& crc_fold_table() {
  static const CrcFoldTable table;
  return table;
}

// clang 18 to 20 gate 512-bit vectors on "evex512" too (AVX10); clang 21
// dropped the name again and gcc 12 never knew it.
#if defined(__clang__) && __clang_major__ >= 18 && __clang_major__ <= 20
#define WIRETAPE_CRC32C_FOLD_TARGET \
  __attribute__((target("sse4.2,crc32,pclmul,avx512f,avx512vl,vpclmulqdq,evex512")))
#else
#define WIRETAPE_CRC32C_FOLD_TARGET \
  __attribute__((target("sse4.2,crc32,pclmul,avx512f,avx512vl,vpclmulqdq")))
#endif

WIRETAPE_CRC32C_FOLD_TARGET inline __m512i fold_512(__m512i blocks, __m512i constants,
                                                    __m512i ahead) {
  const __m512i first = _mm512_clmulepi64_epi128(blocks, constants, 0x00);
  const __m512i second = _mm512_clmulepi64_epi128(blocks, constants, 0x11);
  return _mm512_ternarylogic_epi64(first, second, ahead, 0x96);  // three-way xor
}

WIRETAPE_CRC32C_FOLD_TARGET inline __m128i fold_128(__m128i block, __m128i constants,
                                                    __m128i ahead) {
  const __m128i first = _mm_clmulepi64_si128(block, constants, 0x00);
  const __m128i second = _mm_clmulepi64_si128(block, constants, 0x11);
  return _mm_xor_si128(_mm_xor_si128(first, second), ahead);
}

WIRETAPE_CRC32C_FOLD_TARGET inline __m512i broadcast(const CrcFoldConstants& k) {
  const auto first = static_cast<long long>(k.first_half);
  const auto second = static_cast<long long>(k.second_half);
  return _mm512_set_epi64(second, first, second, first, second, first, second, first);
}

constexpr std::size_t crc_fold_minimum = 256;

WIRETAPE_CRC32C_FOLD_TARGET std::uint32_t crc32c_folding(const void* data, std::size_t size,
                                                          std::uint32_t crc) {
  if (size < crc_fold_minimum) return crc32c_instructions(data, size, crc);
  const auto* p = static_cast<const unsigned char*>(data);
  const CrcFoldTable& table = crc_fold_table();
  // The register enters as the first four bytes' xor, as in the instruction.
  __m512i x0 = _mm512_xor_si512(_mm512_loadu_si512(p),
                                _mm512_set_epi64(0, 0, 0, 0, 0, 0, 0, static_cast<long long>(~crc)));
  __m512i x1 = _mm512_loadu_si512(p + 64);
  __m512i x2 = _mm512_loadu_si512(p + 128);
  __m512i x3 = _mm512_loadu_si512(p + 192);
  p += 256;
  size -= 256;
  const __m512i by_256 = broadcast(table.by_256);
  while (size >= 256) {
    x0 = fold_512(x0, by_256, _mm512_loadu_si512(p));
    x1 = fold_512(x1, by_256, _mm512_loadu_si512(p + 64));
    x2 = fold_512(x2, by_256, _mm512_loadu_si512(p + 128));
    x3 = fold_512(x3, by_256, _mm512_loadu_si512(p + 192));
    p += 256;
    size -= 256;
  }
  const __m512i by_64 = broadcast(table.by_64);
  __m512i x = fold_512(x0, by_64, x1);
  x = fold_512(x, by_64, x2);
  x = fold_512(x, by_64, x3);
  while (size >= 64) {
    x = fold_512(x, by_64, _mm512_loadu_si512(p));
    p += 64;
    size -= 64;
  }
  const __m128i by_16 = _mm_set_epi64x(static_cast<long long>(table.by_16.second_half),
                                       static_cast<long long>(table.by_16.first_half));
  alignas(64) __m128i lanes[4];
  _mm512_store_si512(lanes, x);
  __m128i v = fold_128(lanes[0], by_16, lanes[1]);
  v = fold_128(v, by_16, lanes[2]);
  v = fold_128(v, by_16, lanes[3]);
  while (size >= 16) {
    v = fold_128(v, by_16, _mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
    p += 16;
    size -= 16;
  }
  // The last block, fed with an empty register, is its own remainder.
  std::uint64_t register_value = _mm_crc32_u64(0, static_cast<std::uint64_t>(_mm_cvtsi128_si64(v)));
  register_value = _mm_crc32_u64(register_value,
                                 static_cast<std::uint64_t>(_mm_extract_epi64(v, 1)));
  // The tail goes through the instruction path, which inverts on entry and exit.
  return crc32c_instructions(p, size, ~static_cast<std::uint32_t>(register_value));
}

bool cpu_has_crc_folding() {
  return cpu_has_crc32c() && cpu_features().pclmul && cpu_features().avx512_folding;
}
#endif

using Crc32cFunction = std::uint32_t (*)(const void*, std::size_t, std::uint32_t);

Crc32cFunction pick_crc32c() {
#ifdef WIRETAPE_CRC32C_HARDWARE
  if (cpu_has_crc32c()) {
    // Built now so that the first checksum on a recording thread does not.
    crc_long_shift();
    crc_middle_shift();
    crc_short_shift();
#ifdef WIRETAPE_CRC32C_FOLDING
    if (cpu_has_crc_folding()) {
      crc_fold_table();
      return crc32c_folding;
    }
#endif
    return crc32c_instructions;
  }
#endif
  return detail::crc32c_table;
}

}  // namespace

namespace detail {

std::uint32_t crc32c_table(const void* data, std::size_t size, std::uint32_t crc) {
  const CrcTables& t = crc_tables();
  const auto* p = static_cast<const unsigned char*>(data);
  crc = ~crc;
  while (size >= 8) {
    const std::uint32_t low = crc ^ (static_cast<std::uint32_t>(p[0]) |
                                     (static_cast<std::uint32_t>(p[1]) << 8) |
                                     (static_cast<std::uint32_t>(p[2]) << 16) |
                                     (static_cast<std::uint32_t>(p[3]) << 24));
    crc = t[7][low & 0xFF] ^ t[6][(low >> 8) & 0xFF] ^ t[5][(low >> 16) & 0xFF] ^
          t[4][low >> 24] ^ t[3][p[4]] ^ t[2][p[5]] ^ t[1][p[6]] ^ t[0][p[7]];
    p += 8;
    size -= 8;
  }
  while (size-- > 0) crc = (crc >> 8) ^ t[0][(crc ^ *p++) & 0xFF];
  return ~crc;
}

bool crc32c_hardware_available() {
#ifdef WIRETAPE_CRC32C_HARDWARE
  return cpu_has_crc32c();
#else
  return false;
#endif
}

std::uint32_t crc32c_hardware(const void* data, std::size_t size, std::uint32_t crc) {
#ifdef WIRETAPE_CRC32C_HARDWARE
  if (cpu_has_crc32c()) return crc32c_instructions(data, size, crc);
#endif
  return crc32c_table(data, size, crc);
}

bool crc32c_folding_available() {
#ifdef WIRETAPE_CRC32C_FOLDING
  return cpu_has_crc_folding();
#else
  return false;
#endif
}

std::uint32_t crc32c_folded(const void* data, std::size_t size, std::uint32_t crc) {
#ifdef WIRETAPE_CRC32C_FOLDING
  if (cpu_has_crc_folding()) return crc32c_folding(data, size, crc);
#endif
  return crc32c_hardware(data, size, crc);
}

}  // namespace detail

std::uint32_t crc32c(const void* data, std::size_t size, std::uint32_t crc) {
  static const Crc32cFunction implementation = pick_crc32c();
  return implementation(data, size, crc);
}

}  // namespace wiretape
