import sys, collections, statistics as st
rows=[l.split() for l in open(sys.argv[1]) if len(l.split())>=8]
d=collections.defaultdict(list); order=[]
for r in rows:
  k=(r[0],r[2]); 
  if k not in d: order.append(k)
  d[k].append((float(r[3])+float(r[4]),float(r[6]),float(r[7])))
print("%-12s %-10s %3s %7s %10s %10s %10s %8s"%("scene","arm","n","cpu","mean","median","max","mstd"))
for k in order:
  v=d[k]; n=len(v)
  print("%-12s %-10s %3d %7.2f %10.3e %10.3e %10.3e %8.4f"%(k[0],k[1],n,sum(x[0] for x in v)/n,sum(x[1] for x in v)/n,st.median([x[1] for x in v]),max(x[1] for x in v),st.pstdev([x[2] for x in v]) if n>1 else 0))
