import numpy as np
rng=np.random.default_rng(1)
def run(p,B,D,n,N=200000,mode='new'):
    x=np.where(rng.random((N,n))<p,B,D)
    a=x[:,0::2].mean(1); b=x[:,1::2].mean(1)
    d=a-b
    tot=x.sum(1); mx=x.max(1); t=(tot-mx)/(n-1)
    ms=np.maximum(a*b,0)
    if mode=='new' and n>=3: ms=np.maximum(ms,t*t)
    est=(d*d/4/(ms+0.01)).mean()
    mu=p*B+(1-p)*D; var=p*(1-p)*(B-D)**2/n
    return est, var/(mu*mu+0.01)
for args in [(0.5,2.1,0.01,4),(0.5,2.1,0.01,8),(0.1,5,0.3,4),(0.1,5,0.3,8),(0.02,20,0.2,4),(0.25,5,0.3,4),(0.5,1,0.9,4),(0.5,2.1,0.01,16)]:
    print(args, 'old %.3f new %.3f true %.3f'%(run(*args,mode='old')[0],*run(*args)))
