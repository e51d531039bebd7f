/* The speed of light for one taylor2 tick: the paper's Eq. 9 on its circle in plain C.
 *
 * Span search, Cox-de Boor basis derivatives (Piegl & Tiller A2.3), the rational quotient
 * rule (A4.2), the trapezoidal profile, one Taylor step: what a straightforward C
 * implementation on a controller does per tick.  benchmarks/run.py compiles it with
 * `gcc -O2` and runs it; it prints the mean ns per tick and a checksum.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#define P 2
#define NCTRL 7
#define DIMH 3

static const double U[] = {0, 0, 0, 0.25, 0.5, 0.5, 0.75, 1, 1, 1};
static const double CP[NCTRL][2] = {{0, 0}, {0, 50}, {100, 50}, {100, 0}, {100, -50}, {0, -50}, {0, 0}};
static const double W[NCTRL] = {1, 0.5, 0.5, 1, 0.5, 0.5, 1};
static double Pw[NCTRL][DIMH];

static int find_span(double u) {
    int n = NCTRL - 1;
    if (u >= U[n + 1]) return n;
    int lo = P, hi = n + 1;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (u < U[mid]) hi = mid; else lo = mid;
    }
    return lo;
}

static void ders_basis(int span, double u, int nd, double ders[][P + 1]) {
    double ndu[P + 1][P + 1], a[2][P + 1], left[P + 1], right[P + 1];
    ndu[0][0] = 1.0;
    for (int j = 1; j <= P; j++) {
        left[j] = u - U[span + 1 - j];
        right[j] = U[span + j] - u;
        double saved = 0.0;
        for (int r = 0; r < j; r++) {
            ndu[j][r] = right[r + 1] + left[j - r];
            double temp = ndu[r][j - 1] / ndu[j][r];
            ndu[r][j] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        ndu[j][j] = saved;
    }
    for (int j = 0; j <= P; j++) ders[0][j] = ndu[j][P];
    for (int r = 0; r <= P; r++) {
        int s1 = 0, s2 = 1;
        a[0][0] = 1.0;
        for (int k = 1; k <= nd; k++) {
            double d = 0.0;
            int rk = r - k, pk = P - k;
            if (r >= k) { a[s2][0] = a[s1][0] / ndu[pk + 1][rk]; d = a[s2][0] * ndu[rk][pk]; }
            int j1 = rk >= -1 ? 1 : -rk;
            int j2 = (r - 1 <= pk) ? k - 1 : P - r;
            for (int j = j1; j <= j2; j++) {
                a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][rk + j];
                d += a[s2][j] * ndu[rk + j][pk];
            }
            if (r <= pk) { a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r]; d += a[s2][k] * ndu[r][pk]; }
            ders[k][r] = d;
            int t = s1; s1 = s2; s2 = t;
        }
    }
    int f = P;
    for (int k = 1; k <= nd; k++) {
        for (int j = 0; j <= P; j++) ders[k][j] *= f;
        f *= P - k;
    }
}

/* C'(u) and C''(u) (and C(u)) of the rational curve */
static void curve_ders(double u, double CK[3][2]) {
    double ders[3][P + 1], Aw[3][DIMH];
    int span = find_span(u);
    ders_basis(span, u, 2, ders);
    for (int k = 0; k <= 2; k++)
        for (int c = 0; c < DIMH; c++) {
            double s = 0.0;
            for (int j = 0; j <= P; j++) s += ders[k][j] * Pw[span - P + j][c];
            Aw[k][c] = s;
        }
    for (int c = 0; c < 2; c++) {
        CK[0][c] = Aw[0][c] / Aw[0][2];
        CK[1][c] = (Aw[1][c] - Aw[1][2] * CK[0][c]) / Aw[0][2];
        CK[2][c] = (Aw[2][c] - 2.0 * Aw[1][2] * CK[1][c] - Aw[2][2] * CK[0][c]) / Aw[0][2];
    }
}

int main(int argc, char **argv) {
    const double Vp = 100.0, Ta = 0.5, T = argc > 1 ? atof(argv[1]) : 1e-3, L = 100.0 * M_PI;
    const double tend = L / Vp + Ta, td = tend - Ta;
    for (int i = 0; i < NCTRL; i++) { Pw[i][0] = CP[i][0] * W[i]; Pw[i][1] = CP[i][1] * W[i]; Pw[i][2] = W[i]; }
    long K = (long)ceil(tend / T);
    int passes = argc > 2 ? atoi(argv[2]) : 200;
    double checksum = 0.0;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (int pass = 0; pass < passes; pass++) {
        double u = 0.0;
        for (long k = 0; k <= K; k++) {
            double t = k * T, V, A, CK[3][2];
            if (t < Ta) { V = Vp * t / Ta; A = Vp / Ta; }
            else if (t < td) { V = Vp; A = 0.0; }
            else if (t < tend) { V = Vp * (1.0 - (t - td) / Ta); A = -Vp / Ta; }
            else { V = 0.0; A = 0.0; }
            curve_ders(u, CK);
            checksum += CK[0][0] + CK[0][1];
            double sigma = sqrt(CK[1][0] * CK[1][0] + CK[1][1] * CK[1][1]);
            double dot = CK[1][0] * CK[2][0] + CK[1][1] * CK[2][1];
            double step = T * V / sigma;
            double nxt = u + step + 0.5 * T * T * A / sigma - 0.5 * step * step * dot / (sigma * sigma);
            u = nxt < u ? u : (nxt > 1.0 ? 1.0 : nxt);
        }
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double ns = (t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec);
    printf("%.3f %.6f\n", ns / ((double)passes * (K + 1)), checksum);
    return 0;
}
