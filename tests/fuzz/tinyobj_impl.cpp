// tinyobjloader's implementation, compiled from Debian's header into the OBJ fuzzer (instead
// of linking libtinyobjloader.so) so that the sanitizers and coverage see inside it.
#define TINYOBJLOADER_IMPLEMENTATION
#include <tiny_obj_loader.h>
