/* bind_slice.c: Lua binding of the slice primitive (to be written). */
#include "bind.h"

int gr_open_slice(lua_State *L) {
  (void)L;
  return 0;
}
