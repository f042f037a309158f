// micro: per-cycle cost of update_centres + collide on the Table 2 scenario at small n.
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <bpx/bpx.h>
#include "demo_sim.h"
static double now(void){struct timespec t;clock_gettime(CLOCK_MONOTONIC,&t);return t.tv_sec+t.tv_nsec*1e-9;}
static int cmpd(const void*a,const void*b){double x=*(double*)a,y=*(double*)b;return x<y?-1:x>y;}
int main(int argc,char**argv){
  uint32_t n=argc>1?atoi(argv[1]):50; const char*bn=argc>2?argv[2]:"auto"; int frames=argc>3?atoi(argv[3]):2000; int batches=argc>4?atoi(argv[4]):200;
  demo_params p=demo_default_params(); p.sphere_count=n; p.seed=1; demo_sim*sim; demo_error e;
  if(demo_sim_create(&p,NULL,&sim,&e)){fprintf(stderr,"%s\n",e.message);return 1;}
  float*c=malloc(sizeof(float)*3*n*frames); float*mn=malloc(sizeof(float)*3*n);
  for(size_t k=0;k<3*n;k++) mn[k]=-(float)p.radius;
  for(int f=0;f<frames;f++){const double*pos=demo_sim_positions(sim);for(size_t k=0;k<3*n;k++)c[(size_t)f*3*n+k]=(float)pos[k];demo_sim_step(sim,NULL,&e);}
  bpx_world_def d=bpx_default_world_def(); d.worker_count=1; bpx_backend_from_name(bn,&d.backend); if(argc>5) bpx_simd_from_name(argv[5],&d.simd);
  bpx_world*w; if(bpx_world_create(&d,&w)){fprintf(stderr,"create\n");return 1;}
  bpx_world_load_extents(w,mn,n);
  int hot=argc>6?atoi(argv[6]):0; float*hb=malloc(sizeof(float)*3*n);
  size_t total=(size_t)batches*frames; double*t=malloc(sizeof(double)*total); double up=0,cmp=0,em=0,tst=0; uint64_t sum=0; size_t k=0;
  for(int b=0;b<batches;b++) for(int f=0;f<frames;f++){const float*src=c+(size_t)f*3*n; if(hot){memcpy(hb,src,sizeof(float)*3*n); src=hb;}
    double s=now(); bpx_world_update_centres(w,src);bpx_world_collide(w); t[k++]=(now()-s)*1e6;
    bpx_cycle_stats st=bpx_world_stats(w);sum+=st.pair_count;tst+=st.pair_tests;up+=st.update_ns;cmp+=st.compare_ns;em+=st.emit_ns;}
  double mean=0; for(size_t q=0;q<total;q++) mean+=t[q]; mean/=total;
  qsort(t,total,sizeof(double),cmpd);
  printf("n=%u %s hot=%d median %.3f us/cycle mean %.3f pairs/cycle %.2f  stats: update %.0f ns compare %.0f ns emit %.0f ns tests %.0f\n",n,bn,hot,t[total/2],mean,(double)sum/total,up/total,cmp/total,em/total,tst/total);
  return 0;}
