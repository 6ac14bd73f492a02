/* expr.c: see expr.h. A tokenizer and recursive-descent parser emit a flat
 * stack-machine program (constant sub-expressions folded while emitting);
 * evaluation runs the program over chunks of CHUNK points with one column of
 * CHUNK doubles per stack slot, so the interpreter overhead is paid once per
 * chunk, not per point. The compiled program is immutable (thread-safe). */
#include "expr.h"
#include "vecmath.h"
#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define CHUNK 256      /* points per evaluation chunk */
#define STACK_SLOTS 16 /* stack depth served from the C stack; deeper: heap */
#define MAX_DEPTH 256  /* nesting limit, keeps the parser's recursion bounded */

enum {
  OP_CONST, OP_VAR, OP_ADD, OP_SUB, OP_MUL, OP_DIV, OP_POW, OP_NEG,
  /* one-argument functions, same order as FUNCS below */
  OP_SIN, OP_COS, OP_TAN, OP_ASIN, OP_ACOS, OP_ATAN, OP_EXP, OP_LOG,
  OP_SQRT, OP_ABS, OP_FLOOR,
  /* two-argument functions */
  OP_MIN, OP_MAX, OP_ATAN2
};

typedef struct func_def {
  const char *name; /* as written in expressions */
  int op1;          /* opcode with one argument, -1 if not allowed */
  int op2;          /* opcode with two arguments, -1 if not allowed */
} func_def;

static const func_def FUNCS[] = {
  {"sin", OP_SIN, -1},   {"cos", OP_COS, -1},   {"tan", OP_TAN, -1},
  {"asin", OP_ASIN, -1}, {"acos", OP_ACOS, -1}, {"atan", OP_ATAN, OP_ATAN2},
  {"exp", OP_EXP, -1},   {"log", OP_LOG, -1},   {"sqrt", OP_SQRT, -1},
  {"abs", OP_ABS, -1},   {"min", -1, OP_MIN},   {"max", -1, OP_MAX},
  {"floor", OP_FLOOR, -1},
};
#define NFUNCS ((int)(sizeof FUNCS / sizeof FUNCS[0]))

/* A binary operation's right operand: the stack's top, or fused into the
 * operation (a constant or a variable pushed just before it: one pass over
 * the chunk instead of two, the same arithmetic). */
enum { R_STACK, R_CONST, R_VAR };

typedef struct instr {
  int op;   /* OP_* */
  int var;  /* variable index for OP_VAR (and rk R_VAR) */
  double c; /* value for OP_CONST (and rk R_CONST) */
  int rk;   /* binary operations: R_* */
} instr;

struct gr_expr {
  char *src;      /* source text */
  int nvars;      /* number of variables */
  char **vars;    /* their names (for error messages) */
  instr *code;    /* program */
  size_t ncode;   /* instructions */
  int maxdepth;   /* stack slots needed */
};

/* ---- parser state ---- */
typedef struct parser {
  const char *src;
  size_t pos;            /* current byte offset */
  int nvars;
  const char *const *vars;
  int nconst;
  const char *const *cnames;
  const double *cvals;
  instr *code;           /* program being emitted */
  size_t ncode, cap;
  int depth, maxdepth;   /* simulated stack depth */
  int nest;              /* recursion depth */
  gr_err *e;
  int failed;
} parser;

/* printf arguments "%.*s%s" quoting a source, cut to 80 characters so that
 * the message after it is never lost to truncation. */
#define SRC_MAX 80
#define SRC_ARGS(s) (strlen(s) > SRC_MAX ? SRC_MAX - 3 : (int)strlen(s)), (s), \
                    (strlen(s) > SRC_MAX ? "..." : "")

/* Report a syntax error at byte offset `at` (column at+1), once. */
static int perr(parser *p, size_t at, const char *what) {
  if (!p->failed)
    gr_fail(p->e, GR_EPARSE, "expression '%.*s%s' col %d: %s", SRC_ARGS(p->src), (int)at + 1,
            what);
  p->failed = 1;
  return -1;
}

static void skip_ws(parser *p) {
  while (p->src[p->pos] && isspace((unsigned char)p->src[p->pos])) p->pos++;
}

static double apply1(int op, double a) {
  switch (op) {
  case OP_NEG: return -a;
  case OP_SIN: return sin(a);
  case OP_COS: return cos(a);
  case OP_TAN: return tan(a);
  case OP_ASIN: return asin(a);
  case OP_ACOS: return acos(a);
  case OP_ATAN: return atan(a);
  case OP_EXP: return exp(a);
  case OP_LOG: return log(a);
  case OP_SQRT: return sqrt(a);
  case OP_ABS: return fabs(a);
  case OP_FLOOR: return floor(a);
  }
  return NAN;
}

static double apply2(int op, double a, double b) {
  switch (op) {
  case OP_ADD: return a + b;
  case OP_SUB: return a - b;
  case OP_MUL: return a * b;
  case OP_DIV: return a / b;
  case OP_POW: return pow(a, b);
  case OP_MIN: return a < b ? a : b;
  case OP_MAX: return a > b ? a : b;
  case OP_ATAN2: return atan2(a, b);
  }
  return NAN;
}

static int is_unary(int op) { return op == OP_NEG || (op >= OP_SIN && op <= OP_FLOOR); }

/* Append one instruction, folding it into a constant when its operands are
 * constants (the last one or two instructions). Tracks the stack depth. */
static int emit(parser *p, int op, int var, double c) {
  if (is_unary(op) && p->ncode >= 1 && p->code[p->ncode - 1].op == OP_CONST) {
    p->code[p->ncode - 1].c = apply1(op, p->code[p->ncode - 1].c);
    return 0;
  }
  if (op >= OP_ADD && op != OP_NEG && !is_unary(op) && p->ncode >= 2 &&
      p->code[p->ncode - 1].op == OP_CONST && p->code[p->ncode - 2].op == OP_CONST) {
    p->code[p->ncode - 2].c = apply2(op, p->code[p->ncode - 2].c, p->code[p->ncode - 1].c);
    p->ncode--;
    p->depth--;
    return 0;
  }
  if (op >= OP_ADD && op != OP_NEG && !is_unary(op) && p->ncode >= 1 &&
      (p->code[p->ncode - 1].op == OP_CONST || p->code[p->ncode - 1].op == OP_VAR)) {
    instr *r = &p->code[p->ncode - 1]; /* the whole right operand */
    r->rk = r->op == OP_CONST ? R_CONST : R_VAR;
    r->op = op;
    p->depth--;
    return 0;
  }
  if (gr_grow(&p->code, &p->cap, p->ncode + 1, sizeof *p->code) != GR_OK) {
    if (!p->failed) gr_fail(p->e, GR_EMEM, "expression '%s': out of memory", p->src);
    p->failed = 1;
    return -1;
  }
  p->code[p->ncode++] = (instr){op, var, c, R_STACK};
  if (op == OP_CONST || op == OP_VAR) {
    if (++p->depth > p->maxdepth) p->maxdepth = p->depth;
  } else if (!is_unary(op)) {
    p->depth--;
  }
  return 0;
}

static int parse_expr(parser *p);
static int parse_unary(parser *p);

/* Text listing the allowed names, for "unknown name" errors. */
static void allowed_names(const parser *p, char *buf, size_t n) {
  size_t k = 0;
  k += snprintf(buf + k, n - k, "variables: ");
  for (int i = 0; i < p->nvars && k < n; i++)
    k += snprintf(buf + k, n - k, "%s%s", i ? ", " : "", p->vars[i]);
  if (!p->nvars && k < n) k += snprintf(buf + k, n - k, "none");
  if (k < n) k += snprintf(buf + k, n - k, "; constants: pi");
  for (int i = 0; i < p->nconst && k < n; i++)
    k += snprintf(buf + k, n - k, ", %s", p->cnames[i]);
  if (k < n) k += snprintf(buf + k, n - k, "; functions: ");
  for (int i = 0; i < NFUNCS && k < n; i++)
    k += snprintf(buf + k, n - k, "%s%s", i ? " " : "", FUNCS[i].name);
}

/* primary := number | name | name '(' args ')' | '(' expr ')' */
static int parse_primary(parser *p) {
  skip_ws(p);
  const char *s = p->src;
  size_t start = p->pos;
  char ch = s[p->pos];
  if (isdigit((unsigned char)ch) || (ch == '.' && isdigit((unsigned char)s[p->pos + 1]))) {
    /* digits [. digits] [e [+-] digits]: scanned here so that strtod never
     * sees hex, "inf" or "nan" */
    size_t q = p->pos;
    while (isdigit((unsigned char)s[q])) q++;
    if (s[q] == '.') { q++; while (isdigit((unsigned char)s[q])) q++; }
    if (s[q] == 'e' || s[q] == 'E') {
      size_t r = q + 1;
      if (s[r] == '+' || s[r] == '-') r++;
      if (!isdigit((unsigned char)s[r])) return perr(p, r, "bad number exponent");
      while (isdigit((unsigned char)s[r])) r++;
      q = r;
    }
    char buf[64];
    if (q - p->pos >= sizeof buf) return perr(p, start, "number too long");
    memcpy(buf, s + p->pos, q - p->pos);
    buf[q - p->pos] = 0;
    p->pos = q;
    return emit(p, OP_CONST, 0, strtod(buf, NULL));
  }
  if (isalpha((unsigned char)ch) || ch == '_') {
    size_t q = p->pos;
    while (isalnum((unsigned char)s[q]) || s[q] == '_') q++;
    size_t len = q - p->pos;
    p->pos = q;
    skip_ws(p);
    if (s[p->pos] == '(') {
      int f = -1;
      for (int i = 0; i < NFUNCS; i++)
        if (strlen(FUNCS[i].name) == len && !strncmp(FUNCS[i].name, s + start, len)) f = i;
      if (f < 0) {
        char msg[400], names[300];
        allowed_names(p, names, sizeof names);
        snprintf(msg, sizeof msg, "unknown function '%.*s' (%s)", (int)len, s + start, names);
        return perr(p, start, msg);
      }
      p->pos++;
      int nargs = 0;
      skip_ws(p);
      if (s[p->pos] != ')') {
        for (;;) {
          if (parse_expr(p)) return -1;
          nargs++;
          skip_ws(p);
          if (s[p->pos] == ',') { p->pos++; continue; }
          break;
        }
      }
      if (s[p->pos] != ')') return perr(p, p->pos, "expected ')'");
      p->pos++;
      int op = nargs == 1 ? FUNCS[f].op1 : nargs == 2 ? FUNCS[f].op2 : -1;
      if (op < 0) {
        char msg[128];
        const char *want = FUNCS[f].op1 >= 0 && FUNCS[f].op2 >= 0 ? "1 or 2"
                           : FUNCS[f].op1 >= 0 ? "1" : "2";
        snprintf(msg, sizeof msg, "%s() takes %s argument%s, got %d", FUNCS[f].name, want,
                 strcmp(want, "1") ? "s" : "", nargs);
        return perr(p, start, msg);
      }
      return emit(p, op, 0, 0);
    }
    for (int i = 0; i < p->nvars; i++)
      if (strlen(p->vars[i]) == len && !strncmp(p->vars[i], s + start, len))
        return emit(p, OP_VAR, i, 0);
    for (int i = 0; i < p->nconst; i++)
      if (strlen(p->cnames[i]) == len && !strncmp(p->cnames[i], s + start, len))
        return emit(p, OP_CONST, 0, p->cvals[i]);
    if (len == 2 && !strncmp(s + start, "pi", 2)) return emit(p, OP_CONST, 0, M_PI);
    char msg[420], names[300];
    allowed_names(p, names, sizeof names);
    int isfunc = 0;
    for (int i = 0; i < NFUNCS; i++)
      if (strlen(FUNCS[i].name) == len && !strncmp(FUNCS[i].name, s + start, len)) isfunc = 1;
    if (isfunc)
      snprintf(msg, sizeof msg, "expected '(' after function '%.*s'", (int)len, s + start);
    else
      snprintf(msg, sizeof msg, "unknown name '%.*s' (%s)", (int)len, s + start, names);
    return perr(p, start, msg);
  }
  if (ch == '(') {
    p->pos++;
    if (parse_expr(p)) return -1;
    skip_ws(p);
    if (s[p->pos] != ')') return perr(p, p->pos, "expected ')'");
    p->pos++;
    return 0;
  }
  if (!ch) return perr(p, p->pos, "unexpected end, expected a number, name or '('");
  char msg[80];
  snprintf(msg, sizeof msg, "unexpected '%c', expected a number, name or '('", ch);
  return perr(p, p->pos, msg);
}

/* power := primary ['^' unary]: right associative, and the exponent may
 * carry a sign (2^-1); unary minus binds looser (-x^2 = -(x^2)). */
static int parse_power(parser *p) {
  if (parse_primary(p)) return -1;
  skip_ws(p);
  if (p->src[p->pos] == '^') {
    p->pos++;
    if (parse_unary(p)) return -1;
    return emit(p, OP_POW, 0, 0);
  }
  return 0;
}

static int parse_unary(parser *p) {
  skip_ws(p);
  if (++p->nest > MAX_DEPTH) return perr(p, p->pos, "expression nested too deeply");
  int r;
  char ch = p->src[p->pos];
  if (ch == '-' || ch == '+') {
    p->pos++;
    r = parse_unary(p);
    if (!r && ch == '-') r = emit(p, OP_NEG, 0, 0);
  } else {
    r = parse_power(p);
  }
  p->nest--;
  return r;
}

static int parse_term(parser *p) {
  if (parse_unary(p)) return -1;
  for (;;) {
    skip_ws(p);
    char ch = p->src[p->pos];
    if (ch != '*' && ch != '/') return 0;
    p->pos++;
    if (parse_unary(p)) return -1;
    if (emit(p, ch == '*' ? OP_MUL : OP_DIV, 0, 0)) return -1;
  }
}

static int parse_expr(parser *p) {
  if (++p->nest > MAX_DEPTH) return perr(p, p->pos, "expression nested too deeply");
  if (parse_term(p)) return -1;
  for (;;) {
    skip_ws(p);
    char ch = p->src[p->pos];
    if (ch != '+' && ch != '-') break;
    p->pos++;
    if (parse_term(p)) return -1;
    if (emit(p, ch == '+' ? OP_ADD : OP_SUB, 0, 0)) return -1;
  }
  p->nest--;
  return 0;
}

void gr_expr_free(gr_expr *x) {
  if (!x) return;
  if (x->vars)
    for (int i = 0; i < x->nvars; i++) free(x->vars[i]);
  free(x->vars);
  free(x->code);
  free(x->src);
  free(x);
}

static char *dupstr(const char *s) {
  size_t n = strlen(s) + 1;
  char *d = malloc(n);
  if (d) memcpy(d, s, n);
  return d;
}

gr_expr *gr_expr_compile(const char *src, int nvars, const char *const *vars,
                         int nconst, const char *const *cnames,
                         const double *cvals, gr_err *e) {
  if (!src) { gr_fail(e, GR_EARG, "expression is missing (NULL)"); return NULL; }
  parser p = {0};
  p.src = src;
  p.nvars = nvars;
  p.vars = vars;
  p.nconst = nconst;
  p.cnames = cnames;
  p.cvals = cvals;
  p.e = e;
  skip_ws(&p);
  if (!src[p.pos]) {
    gr_fail(e, GR_EPARSE, "expression '%s' col 1: empty expression", src);
    return NULL;
  }
  if (parse_expr(&p) == 0) {
    skip_ws(&p);
    if (src[p.pos]) {
      char msg[80];
      snprintf(msg, sizeof msg, "unexpected '%c' after the end of the expression", src[p.pos]);
      perr(&p, p.pos, msg);
    }
  }
  if (p.failed) { free(p.code); return NULL; }
  gr_expr *x = calloc(1, sizeof *x);
  if (x) {
    x->src = dupstr(src);
    x->vars = calloc(nvars > 0 ? nvars : 1, sizeof *x->vars);
    x->nvars = nvars;
    x->code = p.code;
    x->ncode = p.ncode;
    x->maxdepth = p.maxdepth;
    p.code = NULL;
  }
  int ok = x && x->src && x->vars;
  for (int i = 0; ok && i < nvars; i++) ok = (x->vars[i] = dupstr(vars[i])) != NULL;
  if (!ok) {
    free(p.code);
    gr_expr_free(x);
    gr_fail(e, GR_EMEM, "expression '%s': out of memory", src);
    return NULL;
  }
  return x;
}

const char *gr_expr_source(const gr_expr *x) { return x ? x->src : ""; }

int gr_expr_uses(const gr_expr *x, int i) {
  for (size_t k = 0; k < x->ncode; k++)
    if ((x->code[k].op == OP_VAR || x->code[k].rk == R_VAR) && x->code[k].var == i) return 1;
  return 0;
}

int gr_expr_smooth(const gr_expr *x) {
  for (size_t k = 0; k < x->ncode; k++) {
    int op = x->code[k].op;
    if (op == OP_ABS || op == OP_FLOOR || op == OP_MIN || op == OP_MAX) return 0;
  }
  return 1;
}

/* Run the program over m <= CHUNK points starting at offset off; stack is
 * maxdepth columns of CHUNK doubles. */
static void run_chunk(const gr_expr *x, size_t off, size_t m,
                      const double *const *vars, double *stack, double *out) {
  int sp = 0; /* next free slot */
  for (size_t k = 0; k < x->ncode; k++) {
    const instr *in = &x->code[k];
    /* top (unary) and second (binary: b op a); formed only when they exist
     * (a pointer before the stack is undefined even unused) */
    double *a = sp >= 1 ? stack + (size_t)(sp - 1) * CHUNK : stack;
    double *b = sp >= 2 ? stack + (size_t)(sp - 2) * CHUNK : stack;
    switch (in->op) {
    case OP_CONST: {
      double *t = stack + (size_t)sp++ * CHUNK;
      for (size_t i = 0; i < m; i++) t[i] = in->c;
      break;
    }
    case OP_VAR: {
      double *t = stack + (size_t)sp++ * CHUNK;
      memcpy(t, vars[in->var] + off, m * sizeof *t);
      break;
    }
/* b op a (a: the top, or the fused right operand r with the top as b) */
#define BIN(OP, F)                                                       \
    case OP:                                                             \
      if (in->rk == R_CONST) {                                           \
        double r = in->c;                                                \
        for (size_t i = 0; i < m; i++) a[i] = F(a[i], r);                \
      } else if (in->rk == R_VAR) {                                      \
        const double *r = vars[in->var] + off;                           \
        for (size_t i = 0; i < m; i++) a[i] = F(a[i], r[i]);             \
      } else {                                                           \
        for (size_t i = 0; i < m; i++) b[i] = F(b[i], a[i]);             \
        sp--;                                                            \
      }                                                                  \
      break;
#define F_ADD(u, v) ((u) + (v))
#define F_SUB(u, v) ((u) - (v))
#define F_MUL(u, v) ((u) * (v))
#define F_DIV(u, v) ((u) / (v))
#define F_MIN(u, v) ((u) < (v) ? (u) : (v))
#define F_MAX(u, v) ((u) > (v) ? (u) : (v))
    BIN(OP_ADD, F_ADD)
    BIN(OP_SUB, F_SUB)
    BIN(OP_MUL, F_MUL)
    BIN(OP_DIV, F_DIV)
    BIN(OP_POW, pow)
    BIN(OP_MIN, F_MIN)
    BIN(OP_MAX, F_MAX)
    BIN(OP_ATAN2, atan2)
#undef F_ADD
#undef F_SUB
#undef F_MUL
#undef F_DIV
#undef F_MIN
#undef F_MAX
#undef BIN
#define UN(OP, EXPR)                                         \
    case OP:                                                 \
      for (size_t i = 0; i < m; i++) a[i] = (EXPR);          \
      break;
    UN(OP_NEG, -a[i])
    case OP_SIN: gr_vsin(m, a); break;
    case OP_COS: gr_vcos(m, a); break;
    UN(OP_TAN, tan(a[i]))
    UN(OP_ASIN, asin(a[i]))
    UN(OP_ACOS, acos(a[i]))
    UN(OP_ATAN, atan(a[i]))
    case OP_EXP: gr_vexp(m, a); break;
    case OP_LOG: gr_vlog(m, a); break;
    UN(OP_SQRT, sqrt(a[i]))
    UN(OP_ABS, fabs(a[i]))
    UN(OP_FLOOR, floor(a[i]))
#undef UN
    }
  }
  memcpy(out + off, stack, m * sizeof *out);
}

int gr_expr_eval(const gr_expr *x, size_t n, const double *const *vars,
                 double *out, gr_err *e) {
  double local[STACK_SLOTS * CHUNK];
  double *stack = local;
  if (x->maxdepth > STACK_SLOTS) {
    stack = malloc((size_t)x->maxdepth * CHUNK * sizeof *stack);
    if (!stack) return gr_fail(e, GR_EMEM, "expression '%s': out of memory", x->src);
  }
  int rc = GR_OK;
  for (size_t off = 0; off < n && rc == GR_OK; off += CHUNK) {
    size_t m = n - off < CHUNK ? n - off : CHUNK;
    run_chunk(x, off, m, vars, stack, out);
    for (size_t i = 0; i < m; i++) {
      double v = out[off + i];
      if (isfinite(v)) continue;
      char pt[256];
      size_t k = 0;
      pt[0] = 0;
      for (int j = 0; j < x->nvars && k < sizeof pt; j++)
        k += snprintf(pt + k, sizeof pt - k, "%s%s=%.6g", j ? ", " : "", x->vars[j],
                      vars[j][off + i]);
      rc = gr_fail(e, GR_ENUM, "expression '%.*s%s' gave %s at %s", SRC_ARGS(x->src),
                   isnan(v) ? "nan" : v > 0 ? "inf" : "-inf", x->nvars ? pt : "(no variables)");
      break;
    }
  }
  if (stack != local) free(stack);
  return rc;
}
