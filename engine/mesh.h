/* mesh.h: indexed triangle meshes, their measures and file formats. */
#ifndef GR_MESH_H
#define GR_MESH_H
#include "common.h"

typedef struct gr_mesh {
  double *v;           /* 3*nv vertex coordinates, mm */
  size_t nv, capv;     /* vertex count, capacity (vertices) */
  uint32_t *f;         /* 3*nf vertex indices; counter-clockwise seen from the
                          positive side of the field (normals point to phi>0) */
  size_t nf, capf;     /* face count, capacity (faces) */
} gr_mesh;

gr_mesh *gr_mesh_new(void);
void gr_mesh_free(gr_mesh *m); /* NULL is fine */
/* Return the new index, or -1 when out of memory. */
long gr_mesh_add_vertex(gr_mesh *m, double x, double y, double z);
int gr_mesh_add_face(gr_mesh *m, uint32_t a, uint32_t b, uint32_t c); /* GR_OK/GR_EMEM */

double gr_mesh_area(const gr_mesh *m);   /* mm^2 */
/* Signed enclosed volume by the divergence theorem (mm^3); meaningful for a
 * closed mesh; positive when normals point outward. */
double gr_mesh_volume(const gr_mesh *m);
void gr_mesh_bounds(const gr_mesh *m, double lo[3], double hi[3]);

typedef struct gr_mesh_topo {
  size_t edges;           /* distinct undirected edges */
  size_t boundary_edges;  /* used by one face */
  size_t nonmanifold_edges; /* used by more than two faces */
  size_t misoriented_edges; /* two faces traverse it the same way */
  size_t degenerate_faces;  /* repeated index or zero area */
  long euler;             /* V - E + F */
} gr_mesh_topo;
int gr_mesh_topology(const gr_mesh *m, gr_mesh_topo *t, gr_err *e);

/* format: "stl" (binary), "stl_ascii", "ply", "obj", or NULL to choose by the
 * path's extension (.stl binary, .ply, .obj). Written atomically. */
int gr_mesh_write(const gr_mesh *m, const char *path, const char *format,
                  gr_err *e);
/* Reads STL (ASCII or binary; coincident vertices merged), OBJ, PLY (ASCII
 * and binary little-endian). Errors name path and line/offset. */
gr_mesh *gr_mesh_read(const char *path, gr_err *e);
/* The same readers on a file's contents in memory (len bytes, need not be
 * NUL-terminated); `name` stands for the path in messages and picks OBJ by
 * its ".obj" ending. Used by the fuzzing harness. */
gr_mesh *gr_mesh_read_mem(const char *name, const void *data, size_t len, gr_err *e);

#endif
