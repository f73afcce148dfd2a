/* Decimal numbers as ground-motion records write them ('-0.12345678E+00',
 * '.1234E-02', '2.5', '1d-3'), read to the nearest double: the value
 * Fortran's read gives (libgfortran hands the digits to strtod too,
 * tests/unit/test_decimal.f90), without the cost of a Fortran read
 * statement per number (bench/records.py). */
#include <fenv.h>
#include <stdint.h>
#include <stdlib.h>

enum { longest = 100 };    /* characters of a number; longer is refused */

/* 10^k, exact in a double up to k = 22. */
static const double powers_of_ten[23] = {
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

/* 0 when text[0 .. length-1] is a decimal number, [+-] digits [. digits]
 * or [+-] . digits, then an optional exponent [eEdD] [+-] digits or, as
 * Fortran writes exponents beyond 99, [+-] digits ('.1234567-100'), with
 * *value its nearest double (beyond the doubles: +-Inf, or 0 and the
 * subnormals below them); 1 when it is not; 2 when it is longer than 100
 * characters.
 *
 * Where the digits, as an integer w, are at most 2^53 and the number is w
 * times or over 10^k with k <= 22, both are exact doubles and one
 * multiplication or division rounds correctly (Clinger 1990): records'
 * numbers, seven or eight digits, take this way. Others go to strtod,
 * which rounds correctly too; where the value may lie beyond the normal
 * doubles it runs with the floating-point exceptions held, since the
 * Debug build traps overflow and strtod raises it on its way to Inf. The
 * text is then copied, NUL-terminated, because the caller's is not. */
int ellroll_decimal_value(const char *text, int length, double *value)
{
    int k = 0, digits = 0, significant = 0, after_point = 0, exponent_digits = 0;
    int negative = 0, exponent_negative = 0;
    uint64_t w = 0;            /* the first 19 significant digits */
    long exponent = 0;
    long magnitude;            /* decimal exponent of the leading digit, about */
    if (length > longest)
        return 2;
    if (length <= 0)
        return 1;
    if (text[k] == '+' || text[k] == '-')
        negative = text[k++] == '-';
    for (; k < length && text[k] >= '0' && text[k] <= '9'; ++k) {
        ++digits;
        if (significant > 0 || text[k] != '0') {
            if (++significant <= 19)
                w = 10 * w + (uint64_t)(text[k] - '0');
        }
    }
    magnitude = significant;
    if (k < length && text[k] == '.') {
        for (++k; k < length && text[k] >= '0' && text[k] <= '9'; ++k) {
            ++digits;
            ++after_point;
            if (significant > 0 || text[k] != '0') {
                if (++significant <= 19)
                    w = 10 * w + (uint64_t)(text[k] - '0');
            } else {
                --magnitude;
            }
        }
    }
    if (digits == 0)
        return 1;
    int letterless = -1;       /* where a signed exponent without a letter begins ('.1234567-100') */
    if (k < length && (text[k] == 'e' || text[k] == 'E' || text[k] == 'd' || text[k] == 'D' ||
                       text[k] == '+' || text[k] == '-')) {
        if (text[k] == '+' || text[k] == '-')
            letterless = k;
        else
            ++k;
        if (k < length && (text[k] == '+' || text[k] == '-'))
            exponent_negative = text[k++] == '-';
        for (; k < length && text[k] >= '0' && text[k] <= '9'; ++k, ++exponent_digits)
            if (exponent < 100000)
                exponent = 10 * exponent + (text[k] - '0');
        if (exponent_digits == 0)
            return 1;
        if (exponent_negative)
            exponent = -exponent;
    }
    if (k != length)
        return 1;

    /* the fast way: w exact (19 digits or fewer, at most 2^53), and w's scale */
    long scale = exponent - after_point;
    if (significant <= 19 && w <= ((uint64_t)1 << 53) && scale >= -22 && scale <= 22) {
        double x = (double)w;
        x = scale < 0 ? x / powers_of_ten[-scale] : x * powers_of_ten[scale];
        *value = negative ? -x : x;
        return 0;
    }

    char copy[longest + 2];
    int n = 0;
    for (k = 0; k < length; ++k) {
        if (k == letterless)
            copy[n++] = 'e';
        copy[n++] = text[k] == 'd' || text[k] == 'D' ? 'e' : text[k];
    }
    copy[n] = '\0';
    magnitude += exponent;
    char *end;
    if (significant > 0 && (magnitude > 300 || magnitude < -300)) {
        fenv_t held;
        feholdexcept(&held);
        *value = strtod(copy, &end);
        fesetenv(&held);
    } else {
        *value = strtod(copy, &end);
    }
    return end == copy + n ? 0 : 1;
}
