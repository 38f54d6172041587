// The instruction sets a vectorised loop of the tracer is built for, the CPU picking one
// when the program loads: AVX-512 as x86-64-v4 (with DQ, whose 64-bit multiply the
// lanes' random number generators use), AVX2, and the baseline. The tracer is compiled
// without fused multiply-adds (CMakeLists.txt), so every clone rounds as the source says
// and a sample's bytes do not depend on the machine's instruction set.
#pragma once

#define ALIQUOT_SIMD_CLONES \
    __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
