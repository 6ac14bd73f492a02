/* bind_io.c: Lua binding of the io primitive (to be written). */
#include "bind.h"

int gr_open_io(lua_State *L) {
  (void)L;
  return 0;
}
