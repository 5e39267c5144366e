// SPDX-License-Identifier: BSD-3-Clause
// CLEANMAP_PER_ISA before a function definition: one clone per instruction set (AVX-512, AVX2,
// baseline), chosen when the library loads; the files using it are compiled with
// -ffp-contract=off, so every clone gives the same bits. Not with clang (14, `make fuzz`), which
// names the dispatcher apart from the symbol that callers in other files use: there the function
// is built once, for the build's -march.
#pragma once

#if defined(__clang__)
#define CLEANMAP_PER_ISA
#else
#define CLEANMAP_PER_ISA __attribute__((target_clones("avx512f", "avx2", "default")))
#endif
