/* The mark of a compiled kernel. The library is compiled with -fvisibility=hidden (the one
 * flag set, models/native/ccompile.py): only the functions marked KERNEL are exported, and
 * they are exactly the kernels of the table in models/native/__init__.py
 * (tests/test_native.py checks both ways). */
#ifndef INS_COSIM_KERNEL_H
#define INS_COSIM_KERNEL_H

#define KERNEL __attribute__((visibility("default")))

#endif
