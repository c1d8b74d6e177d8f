from brdffit.cli import main

raise SystemExit(main())
