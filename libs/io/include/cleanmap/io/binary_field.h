// SPDX-License-Identifier: BSD-3-Clause
// One typed decoder for the binary fields of point-cloud files (PLY and PCD): the type named in a
// header becomes a FieldType with its width, and decode() reads one value of it, any endianness.
#pragma once
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

namespace cleanmap::io {

enum class FieldType : uint8_t { kI8, kU8, kI16, kU16, kI32, kU32, kI64, kU64, kF32, kF64 };

/// Bytes of one value.
std::size_t fieldSize(FieldType t);
/// A PLY property type: char uchar short ushort int uint float double, or int8 uint8 int16 uint16
/// int32 uint32 float32 float64. nullopt for anything else.
std::optional<FieldType> plyFieldType(const std::string& name);
/// A PCD TYPE letter (I, U, F) and SIZE (1, 2, 4, 8). nullopt for a combination PCD does not have.
std::optional<FieldType> pcdFieldType(char type, int size);

/// The value at `p` (unaligned), converted to double. `big_endian` swaps the bytes first.
double decodeField(const char* p, FieldType t, bool big_endian = false);

}  // namespace cleanmap::io
