# Turns a SPIR-V binary into a C++ header with a uint32_t array.
# Usage: cmake -DINPUT=x.spv -DOUTPUT=x.h -DNAME=symbol -P embed_spirv.cmake
file(READ ${INPUT} hex HEX)
string(LENGTH "${hex}" length)
math(EXPR remainder "${length} % 8")
if(NOT remainder EQUAL 0)
  message(FATAL_ERROR "${INPUT}: size is not a multiple of 4 bytes")
endif()
# Little-endian bytes -> 32-bit words.
string(REGEX REPLACE "(..)(..)(..)(..)" "0x\\4\\3\\2\\1u," words "${hex}")
string(REGEX REPLACE "((0x........u,){8})" "\\1\n    " words "${words}")
file(WRITE ${OUTPUT} "// Generated from ${INPUT}; do not edit.\n#pragma once\n#include <cstdint>\ninline constexpr uint32_t ${NAME}[] = {\n    ${words}\n};\n")
