/* bind_field.c: Lua binding of the field primitive (to be written). */
#include "bind.h"

int gr_open_field(lua_State *L) {
  (void)L;
  return 0;
}

gr_field *gr_to_field(lua_State *L, int idx) {
  return gr_field_ref(gr_check_field(L, idx));
}
