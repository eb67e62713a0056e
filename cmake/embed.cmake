# Writes OUT, a C++ file defining `const char* NAME` with the contents of IN.
file(READ "${IN}" content)
file(WRITE "${OUT}.tmp" "// Generated from ${IN}; do not edit.\nnamespace bb::embedded {\nextern const char* const ${NAME};\nconst char* const ${NAME} = R\"bbjson(${content})bbjson\";\n}\n")
file(RENAME "${OUT}.tmp" "${OUT}")
