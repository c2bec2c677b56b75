// toy_softsign: x / (scale + |x|), as torch_twin.py computes it.
float toy_softsign(float x, float scale) {
    return x / (scale + abs(x));
}
