/* CHOLMOD's side of scripts/cholmod_compare.sh: reads a symmetric matrix
 * (Matrix Market, lower triangle), orders it with the method named on the
 * command line (metis | amd), factors it (supernodal, as CHOLMOD chooses for
 * a 3-D stiffness matrix) and solves with 96 right-hand sides, the
 * precompute's batch. Prints one line: entries of L counted exactly (lnz) and
 * as stored (xsize, relaxed supernodes included), analysis, numeric factor and
 * solve times (best of 3, seconds). Run it with one BLAS thread
 * (OPENBLAS_NUM_THREADS=1), as the model factors.
 * Build: cc -O2 cholmod_compare.c -I/usr/include/suitesparse -lcholmod -lm */
#include <cholmod.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: %s MATRIX.mtx metis|amd\n", argv[0]);
        return 2;
    }
    FILE *f = fopen(argv[1], "r");
    if (!f) {
        fprintf(stderr, "%s: cannot open\n", argv[1]);
        return 1;
    }
    cholmod_common c;
    cholmod_start(&c);
    cholmod_sparse *a = cholmod_read_sparse(f, &c);
    fclose(f);
    if (!a) {
        fprintf(stderr, "%s: not a readable Matrix Market matrix\n", argv[1]);
        return 1;
    }
    c.nmethods = 1;
    c.method[0].ordering = strcmp(argv[2], "amd") == 0 ? CHOLMOD_AMD : CHOLMOD_METIS;
    c.postorder = 1;
    c.supernodal = CHOLMOD_SUPERNODAL;
    double analyse = 1e30, numeric = 1e30, solve = 1e30, lnz = 0, xsize = 0;
    int n = (int)a->nrow;
    cholmod_dense *b = cholmod_zeros(n, 96, CHOLMOD_REAL, &c);
    for (int rep = 0; rep < 3; rep++) {
        double t0 = now();
        cholmod_factor *l = cholmod_analyze(a, &c);
        double t1 = now();
        if (!l || c.status != CHOLMOD_OK) {
            fprintf(stderr, "%s: analysis failed (status %d)\n", argv[1], c.status);
            return 1;
        }
        cholmod_factorize(a, l, &c);
        double t2 = now();
        if (c.status != CHOLMOD_OK) {
            fprintf(stderr, "%s: factorization failed (status %d)\n", argv[1], c.status);
            return 1;
        }
        double *bx = (double *)b->x;
        memset(bx, 0, sizeof(double) * (size_t)n * 96);
        for (int k = 0; k < 96; k++) bx[(size_t)k * n + (size_t)((k * 7919 + rep) % n)] = 1.0;
        double t3 = now();
        cholmod_dense *x = cholmod_solve(CHOLMOD_A, l, b, &c);
        double t4 = now();
        if (t1 - t0 < analyse) analyse = t1 - t0;
        if (t2 - t1 < numeric) numeric = t2 - t1;
        if (t4 - t3 < solve) solve = t4 - t3;
        lnz = c.lnz;
        xsize = l->is_super ? (double)l->xsize : (double)l->nzmax;
        cholmod_free_dense(&x, &c);
        cholmod_free_factor(&l, &c);
    }
    printf("cholmod %s: n %d, nnz(L) exact %.3f M, stored %.3f M, analysis %.3f s, numeric %.3f s, 96-column solve %.1f ms\n",
           argv[2], n, lnz / 1e6, xsize / 1e6, analyse, numeric, solve * 1e3);
    cholmod_free_dense(&b, &c);
    cholmod_free_sparse(&a, &c);
    cholmod_finish(&c);
    return 0;
}
