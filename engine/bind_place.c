/* bind_place.c: Lua binding of the place primitive (to be written). */
#include "bind.h"

int gr_open_place(lua_State *L) {
  (void)L;
  return 0;
}
