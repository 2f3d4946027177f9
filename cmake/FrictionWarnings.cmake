# Warnings as errors for the project's own targets (not imposed on consumers of the package).
function(friction_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic)
  if(FRICTION_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()
