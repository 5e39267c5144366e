// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/io/binary_field.h"

#include <algorithm>
#include <cstring>

namespace cleanmap::io {
namespace {

template <class T>
double read(const char* p, bool big_endian) {
  char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (big_endian) std::reverse(b, b + sizeof(T));  // the project's machines are little-endian
  T v;
  std::memcpy(&v, b, sizeof(T));
  return static_cast<double>(v);
}

}  // namespace

std::size_t fieldSize(FieldType t) {
  switch (t) {
    case FieldType::kI8:
    case FieldType::kU8:
      return 1;
    case FieldType::kI16:
    case FieldType::kU16:
      return 2;
    case FieldType::kI32:
    case FieldType::kU32:
    case FieldType::kF32:
      return 4;
    default:
      return 8;
  }
}

std::optional<FieldType> plyFieldType(const std::string& n) {
  if (n == "char" || n == "int8") return FieldType::kI8;
  if (n == "uchar" || n == "uint8") return FieldType::kU8;
  if (n == "short" || n == "int16") return FieldType::kI16;
  if (n == "ushort" || n == "uint16") return FieldType::kU16;
  if (n == "int" || n == "int32") return FieldType::kI32;
  if (n == "uint" || n == "uint32") return FieldType::kU32;
  if (n == "float" || n == "float32") return FieldType::kF32;
  if (n == "double" || n == "float64") return FieldType::kF64;
  return std::nullopt;
}

std::optional<FieldType> pcdFieldType(char type, int size) {
  const bool f = type == 'F', u = type == 'U', i = type == 'I';
  if (f && size == 4) return FieldType::kF32;
  if (f && size == 8) return FieldType::kF64;
  if (!u && !i) return std::nullopt;
  switch (size) {
    case 1:
      return u ? FieldType::kU8 : FieldType::kI8;
    case 2:
      return u ? FieldType::kU16 : FieldType::kI16;
    case 4:
      return u ? FieldType::kU32 : FieldType::kI32;
    case 8:
      return u ? FieldType::kU64 : FieldType::kI64;
    default:
      return std::nullopt;
  }
}

double decodeField(const char* p, FieldType t, bool big_endian) {
  switch (t) {
    case FieldType::kI8:
      return read<int8_t>(p, big_endian);
    case FieldType::kU8:
      return read<uint8_t>(p, big_endian);
    case FieldType::kI16:
      return read<int16_t>(p, big_endian);
    case FieldType::kU16:
      return read<uint16_t>(p, big_endian);
    case FieldType::kI32:
      return read<int32_t>(p, big_endian);
    case FieldType::kU32:
      return read<uint32_t>(p, big_endian);
    case FieldType::kI64:
      return read<int64_t>(p, big_endian);
    case FieldType::kU64:
      return read<uint64_t>(p, big_endian);
    case FieldType::kF32:
      return read<float>(p, big_endian);
    case FieldType::kF64:
      return read<double>(p, big_endian);
  }
  return 0;
}

}  // namespace cleanmap::io
