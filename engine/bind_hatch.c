/* bind_hatch.c: Lua binding of the hatch primitive (to be written). */
#include "bind.h"

int gr_open_hatch(lua_State *L) {
  (void)L;
  return 0;
}
