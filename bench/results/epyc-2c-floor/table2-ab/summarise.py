import csv,glob,statistics as st,sys,collections
root=sys.argv[1]
# per (version, run, n, variant): mean, median
D=collections.defaultdict(dict)
for f in sorted(glob.glob(root+'/*/table2.csv')):
    tag=f.split('/')[-2]; v,r=tag.rsplit('-',1)
    for row in csv.DictReader(open(f)):
        D[(v,r)][(int(row['n']),row['variant'])]=(float(row['mean_us']),float(row['median_us']),int(row['wrong_cycles']))
vers=sorted(set(k[0] for k in D)); runs=sorted(set(k[1] for k in D))
ns=sorted(set(k[0] for d in D.values() for k in d))
varis=sorted(set(k[1] for d in D.values() for k in d))
wrong=sum(x[2] for d in D.values() for x in d.values())
print('wrong cycles in all runs:',wrong)
for stat,idx in (('mean',0),('median',1)):
  print(f'\n{stat} us per cycle, median over {len(runs)} runs')
  print('| n | '+' | '.join(f'{v} {x}' for v in vers for x in varis)+' |')
  for n in ns:
    cells=[]
    for v in vers:
      for x in varis:
        vals=[D[(v,r)][(n,x)][idx] for r in runs if (n,x) in D[(v,r)]]
        cells.append('%.2f'%st.median(vals) if vals else '-')
    print(f'| {n} | '+' | '.join(cells)+' |')
  # ratios: best bpx (per run) vs bullet-sap fastest of sap/sap32 (per run), median of per-run ratios
  print(f'\nfastest Bullet sweep and prune / best bpx ({stat}s; per run, then median of runs):')
  for n in ns:
    out=[]
    for v in vers:
      rs=[]
      for r in runs:
        d=D[(v,r)]
        b=min(d[(n,x)][idx] for x in varis if not x.startswith('bullet') and (n,x) in d)
        p=min(d[(n,x)][idx] for x in varis if x.startswith('bullet') and (n,x) in d)
        rs.append(p/b)
      out.append(f'{v} %.2fx (%s)'%(st.median(rs),', '.join('%.2f'%q for q in rs)))
    print(f'n={n}: '+'; '.join(out))
