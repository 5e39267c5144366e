// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// CLEANMAP_SANITIZED is defined in a build under AddressSanitizer or ThreadSanitizer (gcc and
// clang): the app then returns from main (the leak check runs), the free space takes its chunks
// from the heap (where the sanitizers watch every access), and a test of malloc's own heap skips.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define CLEANMAP_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define CLEANMAP_SANITIZED 1
#endif
#endif
