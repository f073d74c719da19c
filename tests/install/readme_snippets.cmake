# Fails unless README.md contains each consumer file verbatim: the README's
# "Use it from your code" examples are the files install_test.cmake runs.
#   cmake -DREADME=README.md -P readme_snippets.cmake
file(READ ${README} readme)
foreach(snippet consumer/CMakeLists.txt consumer/main.cpp consumer/render.py)
  file(READ ${CMAKE_CURRENT_LIST_DIR}/${snippet} text)
  string(FIND "${readme}" "${text}" at)
  if(at EQUAL -1)
    message(SEND_ERROR "README.md does not contain tests/install/${snippet} verbatim")
  endif()
endforeach()
