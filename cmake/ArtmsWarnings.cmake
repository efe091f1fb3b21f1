# artms_set_warnings(<target>): the project's warning set, errors in CI.
function(artms_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow
    -Wnon-virtual-dtor -Wold-style-cast -Wcast-align -Woverloaded-virtual
    -Wconversion -Wsign-conversion -Wno-sign-conversion)
  if(ARTMS_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()
