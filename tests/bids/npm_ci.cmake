# npm ci of tests/bids into DEST, once per package-lock.json: a stamp holds
# the lock file's hash, and a later run with the same lock does nothing.
#   cmake -DNPM=npm -DSOURCE=tests/bids -DDEST=build/tests/bids/deps -P npm_ci.cmake
file(SHA256 ${SOURCE}/package-lock.json lock_hash)
set(stamp ${DEST}/npm-ci.stamp)
if(EXISTS ${stamp})
  file(READ ${stamp} done_hash)
  if(done_hash STREQUAL lock_hash AND EXISTS ${DEST}/node_modules/bids-validator/bin/bids-validator)
    return()
  endif()
endif()
file(MAKE_DIRECTORY ${DEST})
file(COPY ${SOURCE}/package.json ${SOURCE}/package-lock.json DESTINATION ${DEST})
execute_process(
  COMMAND ${NPM} ci --prefix ${DEST} --ignore-scripts --no-audit --no-fund --loglevel=error
  RESULT_VARIABLE result)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "npm ci of ${SOURCE} failed (${result})")
endif()
file(WRITE ${stamp} ${lock_hash})
