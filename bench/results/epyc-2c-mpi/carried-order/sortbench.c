// The own-id sort of a rank per collide, 100k ids laid out as the benchmark's after its first
// migrate (four sorted runs) with ~34 objects moving per cycle: the carried order vs the sort.
#include "../src/ids.c"
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
static double now(void){struct timespec t;clock_gettime(CLOCK_MONOTONIC,&t);return t.tv_sec*1e3+t.tv_nsec*1e-6;}
int main(int argc, char **argv){
    size_t n = 100000, N = 200000; int carry = atoi(argv[1]);
    bpx_mpi_world w; memset(&w,0,sizeof w); w.rank=1; w.size=4;
    uint64_t *ids = malloc(N*8); w.home = malloc(N*sizeof(int));
    for (size_t k=0;k<n;k++) ids[k] = (k%4)*1000000 + k; // four runs
    uint64_t next = 10000000; double best=1e9, sum=0; int m=0; srand(1);
    for (int c=0;c<60;c++){
        bool can = w.last_pos_valid && !w.order_hint && n == w.last_ids_count;
        size_t stay=0; for(size_t i=0;i<n;i++){ bool s = rand()%3000!=0; w.home[i]= s?(int)stay:-1; if(s) ids[stay++]=ids[i]; }
        for(int k=0;k<34;k++) ids[stay+k]= next++ * 7 % 5000000 + 8000000; // arrivals: new ids anywhere
        n = stay+34; w.last_pos_valid = w.order_hint = can && carry; w.hint_stay=stay; w.hint_count=n;
        double t=now(); if (bpx_mpi__ids_check_own(&w, ids, n)!=BPX_OK) {printf("err %s\n", w.error.message); return 1;} t=now()-t;
        if(c>=5){ if(t<best)best=t; sum+=t; m++; }
        w.added_count=w.dropped_count=0; bpx_mpi__ids_commit(&w);
    }
    printf("%s: best %.3f ms mean %.3f ms per call (n=%zu)\n", carry?"carried":"sorted", best, sum/m, n);
}
