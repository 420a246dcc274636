# The suite at seed 0 with the multi-view loss (`study hard --seeds 1 --set
# train.multiview.weight=0.5`, runs/hard-*) against the committed `fast` at seed 0 (the span-2
# record's runs, the same recipe), through the colour-grid record's comparison. Run from the
# repository root:
#   python3 results/geometry/cup-multiview-2026-11-27/cmp.py
import runpy, sys
sys.argv = [sys.argv[0], 'cup-multiview-2026-11-27', 'multi-view 0.5', 'multi-view', 'the loss']
runpy.run_path('results/geometry/cup-color-grid-2026-11-27/cmp.py', run_name='__main__')
