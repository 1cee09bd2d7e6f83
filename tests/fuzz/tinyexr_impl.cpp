// tinyexr's implementation, compiled from Debian's header into the image fuzzer (instead of
// linking libtinyexr.so) so that the sanitizers and coverage see inside it.
#define TINYEXR_IMPLEMENTATION
#include <tinyexr.h>
