/* bind_mesh.c: Lua binding of the mesh primitive (to be written). */
#include "bind.h"

int gr_open_mesh(lua_State *L) {
  (void)L;
  return 0;
}
