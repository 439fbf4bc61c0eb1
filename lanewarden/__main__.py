from lanewarden.launcher import main

raise SystemExit(main())
