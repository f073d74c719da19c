# ctest driver: fuzz for a fixed time from a fresh copy of the seed corpus.
# cmake -DFUZZER=<binary> -DSEEDS=<corpus dir> -DWORK=<scratch dir> [-DSECONDS=<n>, default 20]
#       [-DDICT=<libFuzzer dictionary>] -P run_fuzzer.cmake
if(NOT SECONDS)
  set(SECONDS 20)
endif()
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK}/corpus ${WORK}/artifacts)
file(GLOB seeds ${SEEDS}/*)
file(COPY ${seeds} DESTINATION ${WORK}/corpus)
set(dict_option)
if(DICT)
  set(dict_option -dict=${DICT})
endif()
execute_process(
  COMMAND ${FUZZER} ${WORK}/corpus ${dict_option} -max_total_time=${SECONDS} -rss_limit_mb=2048 -print_final_stats=1
          -artifact_prefix=${WORK}/artifacts/
  RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  get_filename_component(name ${FUZZER} NAME)
  message(FATAL_ERROR "${name} failed (exit ${rc}); the reproducer is in ${WORK}/artifacts")
endif()
