/* bind_distance.c: Lua binding of the distance primitive (to be written). */
#include "bind.h"

int gr_open_distance(lua_State *L) {
  (void)L;
  return 0;
}
