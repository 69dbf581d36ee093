# Flags of the AddressSanitizer + UndefinedBehaviorSanitizer workspace that
# `scripts/test.sh --sanitize` builds (read as CMAKE_TOOLCHAIN_FILE; catkin_make keeps -C for
# itself). -O1 keeps the build and the tests fast enough; -g1 gives file:line in the reports.
# UBSan is recoverable at compile time so that UBSAN_OPTIONS decides (test.sh halts on the
# first report).
# EIGEN_MALLOC_ALREADY_ALIGNED=1: under __SANITIZE_ADDRESS__ Eigen switches to its hand-made
# aligned malloc (original pointer stored before the block), while the uninstrumented Debian PCL
# allocates with plain malloc; an Eigen member allocated in libpcl and freed in our code was then
# read 8 bytes before the block (a heap-buffer-overflow report in every ApproximateVoxelGrid and
# SampleConsensus destructor). With the define both sides use malloc as the release build does.
set(OGS_SANITIZE_FLAGS
    "-fsanitize=address,undefined -fno-omit-frame-pointer -g1 -DEIGEN_MALLOC_ALREADY_ALIGNED=1")
set(CMAKE_CXX_FLAGS "${OGS_SANITIZE_FLAGS}" CACHE STRING "" FORCE)
set(CMAKE_C_FLAGS "${OGS_SANITIZE_FLAGS}" CACHE STRING "" FORCE)
set(CMAKE_CXX_FLAGS_RELEASE "-O1 -DNDEBUG" CACHE STRING "" FORCE)
set(CMAKE_C_FLAGS_RELEASE "-O1 -DNDEBUG" CACHE STRING "" FORCE)
set(CMAKE_EXE_LINKER_FLAGS "-fsanitize=address,undefined" CACHE STRING "" FORCE)
set(CMAKE_SHARED_LINKER_FLAGS "-fsanitize=address,undefined" CACHE STRING "" FORCE)
set(CMAKE_MODULE_LINKER_FLAGS "-fsanitize=address,undefined" CACHE STRING "" FORCE)
