// The compact state's device codec (crates/rtmpm-cuda/kernels/codec.cuh), compiled for the CPU:
// codec_encode_c / codec_decode_c (the conversion-free path the kernels use) must give exactly
// the words and values of the generic codec_encode<9, 16> / codec_decode<9, 16> (the twin of
// src/state/codec/mod.rs) on edge cases (zeros, denormals, FLT_MAX, NaN, inf, mantissas rounding past
// 2^15 - 1) and 2M random vectors of mixed scales. Run by scripts/check_codec_twin.sh (in CI);
// the GPU test `the_device_codec_gives_the_host_codec_s_words` checks the same on a GPU.
#include <cstdio>
#include <cstring>
#include <cmath>
#include <cstdlib>
#include <random>
#include <algorithm>
#define __device__
#define __forceinline__ inline
static inline unsigned __float_as_uint(float f){unsigned u; memcpy(&u,&f,4); return u;}
static inline float __uint_as_float(unsigned u){float f; memcpy(&f,&u,4); return f;}
using std::max; using std::min; using std::isfinite;
#include "../crates/rtmpm-cuda/kernels/codec.cuh"
static void old_encode_c(const float c[9], unsigned w[5]) {
    int q[9];
    unsigned code = codec_encode<9, 16>(c, q);
    w[0] = code | ((unsigned)(q[0] & 0xffff) << 16);
    for (int k = 1; k < 5; ++k) w[k] = (unsigned)(q[2 * k - 1] & 0xffff) | ((unsigned)(q[2 * k] & 0xffff) << 16);
}
static void old_decode_c(const unsigned w[5], float c[9]) {
    int q[9];
    q[0] = (int)w[0] >> 16;
    for (int k = 1; k < 5; ++k) { q[2 * k - 1] = (int)(w[k] << 16) >> 16; q[2 * k] = (int)w[k] >> 16; }
    codec_decode<9, 16>(w[0] & 0xffu, q, c);
}
int main(){
  std::mt19937_64 g(7); std::uniform_real_distribution<float> u(-1,1); std::uniform_int_distribution<int> ex(-150,127), sh(-30,3);
  long bad=0, n=0;
  auto check=[&](float c[9]){
    unsigned a[5], b[5]; float da[9], db[9];
    old_encode_c(c,a); codec_encode_c(c,b);
    old_decode_c(a,da); codec_decode_c(a,db);
    n++;
    if (memcmp(a,b,20)) { if(bad<5){printf("enc differs:"); for(int i=0;i<9;i++)printf(" %a",c[i]); printf("\n");} bad++; return; }
    if (memcmp(da,db,36)) { if(bad<5) printf("dec differs\n"); bad++; }
  };
  float edge[][9]={{0},{-0.0f,0,1},{__uint_as_float(1),-__uint_as_float(7),0},{3.4028235e38f,-3.4028235e38f,1},{NAN,1,2},{INFINITY},{2.0f-powf(2,-20),1e-7f,-3}, {32767.5f/32768,1,0},{0.99998474f,-1.0f,0.5f}};
  for(auto&e:edge) check(e);
  for(long t=0;t<2000000;t++){ float c[9]; int e=ex(g); for(int i=0;i<9;i++){ c[i]=u(g)*ldexpf(1.0f,e+sh(g)); if (t%7==0 && i%3==0) c[i]=ldexpf(1.0f, e); if (t%11==0) c[i]=ldexpf(u(g) > 0 ? 32767.5f : -32767.5f, e-15) ; } check(c);}
  // exhaustive rounding near the top: m*s around 32767.5
  for (int k=-4000;k<4000;k++){ float c[9]={0}; c[0]=(32767.5f + k*0.001f); c[1]=-c[0]*0.5f; c[2]=1.0f; for(int j=0;j<3;j++){ float cc[9]; for(int i=0;i<9;i++) cc[i]=ldexpf(c[i], j*40-60); check(cc);} }
  printf("%ld checked, %ld differ\n", n, bad); return bad!=0;
}
